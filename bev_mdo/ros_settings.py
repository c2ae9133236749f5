"""The `ros:` config section: domain, discovery, timeouts, signing, pools. No rclpy import here.

It sits in the config's layer (docs/architecture.md): ``config`` validates the section with it, and
the ROS adapters, sessions and CLI read the validated section through it.

Network hygiene by default: discovery stays on this host (LOCALHOST range) and the
domain id is the project's own. Going across hosts is an explicit opt-in
(`discovery: static_peers | server | subnet`).
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Any, Mapping

from bev_mdo.models.common import check_keys

DEFAULTS: dict[str, Any] = {
    "domain_id": 77,
    "discovery": "localhost",        # localhost | static_peers | server | subnet
    "static_peers": [],              # with static_peers: addresses of the other hosts
    "discovery_server": "",          # with server: "ip:port" of a Fast DDS discovery server
    "timeout_s": 5.0,                # per evaluation wave before a retry
    "retries": 3,
    "discovery_wait_s": 60.0,        # start-up gives up after this long without progress (fastwait.until)
    "sign_key_file": "",             # path of a shared HMAC key: sign and verify every request/result
    "signing": True,                 # a run launched by bev-mdo signs with a fresh per-run key (if no key file)
    "sign_window_s": 30.0,           # signed messages with a stamp further than this from now are expired
    "pool": "share",                 # several instances of a discipline: share | redundant (pool.py)
    "pool_data_flow": True,          # an MDA with a pool: data flow in row shares (true) or waves (false)
    "pool_min_rows": 1,              # smallest share of a pool's batch: N, or {discipline: N} (pool.py)
}
DISCOVERY_MODES = ("localhost", "static_peers", "server", "subnet")


def choose_domain(section: Mapping[str, Any] | None, flag: int | None = None,
                  environ: Mapping[str, str] | None = None) -> tuple[int | None, str | None]:
    """The ROS convention: (domain id, one-line note or None).

    A ``--domain-id`` flag wins, then a ``domain_id`` the config's ``ros:`` section states, then
    ``ROS_DOMAIN_ID`` from the environment, then the project's default (77). The note says when
    the config overrides a different ``ROS_DOMAIN_ID`` of the environment. A domain id that is
    not an integer is returned as given (validate_ros names it)."""
    env = os.environ if environ is None else environ
    raw_env = str(env.get("ROS_DOMAIN_ID", "")).strip()
    env_id = int(raw_env) if raw_env.isdigit() and 0 <= int(raw_env) <= 232 else None
    if flag is not None:
        return flag, None
    section = section or {}
    if section.get("domain_id") is not None:
        d = section["domain_id"]
        note = None
        if env_id is not None and d != env_id:
            note = f"ros.domain_id {d!r} of the config overrides ROS_DOMAIN_ID={raw_env} of the environment"
        return d, note
    if env_id is not None:
        return env_id, None
    return DEFAULTS["domain_id"], None


def check_domain_id(d: Any, name: str = "ros.domain_id") -> int:
    """A ROS domain id: an integer in [0, 232]; ValueError naming ``name`` otherwise (the config's
    ros.domain_id, a Transport's domain_id)."""
    if not isinstance(d, int) or isinstance(d, bool) or not 0 <= d <= 232:
        raise ValueError(f"{name} must be an integer in [0, 232], got {d!r}")
    return d


def validate_ros(section: Mapping[str, Any] | None) -> dict[str, Any]:
    """Fill defaults and check the `ros:` section; one-line ValueError on a mistake."""
    section = dict(section or {})
    check_keys("ros", section, DEFAULTS)
    out = {**DEFAULTS, **section}
    check_domain_id(out["domain_id"])
    if out["discovery"] not in DISCOVERY_MODES:
        raise ValueError(f"ros.discovery must be one of {list(DISCOVERY_MODES)}, got {out['discovery']!r}")
    peers = out["static_peers"]
    if not isinstance(peers, list) or not all(isinstance(a, str) and a and not set(a) & set("; \t,") for a in peers):
        # a string was joined letter by letter into ROS_STATIC_PEERS ('1;0;.;0;...')
        raise ValueError(f"ros.static_peers must be a list of addresses, e.g. ['10.0.0.2'], got {peers!r}")
    if out["discovery"] == "static_peers" and not peers:
        raise ValueError("ros.discovery static_peers needs ros.static_peers: [address, ...]")
    if out["discovery"] == "server" and ":" not in str(out["discovery_server"]):
        raise ValueError("ros.discovery server needs ros.discovery_server: 'ip:port'")
    for key in ("timeout_s", "discovery_wait_s", "sign_window_s"):
        v = out[key]
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not 0 < float(v) < 1e6:
            raise ValueError(f"ros.{key} must be a positive number of seconds, got {v!r}")
        out[key] = float(v)
    key_file = out["sign_key_file"]
    if key_file is None:
        key_file = ""
    if not isinstance(key_file, (str, os.PathLike)):
        raise ValueError(f"ros.sign_key_file must be a path, got {type(key_file).__name__}")
    # Only the (absolute) path is kept: resolved configs, logs and bags never hold the key.
    out["sign_key_file"] = os.path.abspath(os.path.expanduser(str(key_file))) if str(key_file) else ""
    if not isinstance(out["signing"], bool):
        raise ValueError(f"ros.signing must be true or false, got {out['signing']!r}")
    if not isinstance(out["pool_data_flow"], bool):
        raise ValueError(f"ros.pool_data_flow must be true or false, got {out['pool_data_flow']!r}")
    out["pool_min_rows"] = validate_min_rows(out["pool_min_rows"])
    if out["pool"] not in ("share", "redundant"):
        raise ValueError(f"ros.pool must be one of ['share', 'redundant'], got {out['pool']!r}")
    if not isinstance(out["retries"], int) or isinstance(out["retries"], bool) or not 0 <= out["retries"] <= 100:
        raise ValueError(f"ros.retries must be an integer in [0, 100], got {out['retries']!r}")
    return out


LAUNCHED = "BEV_MDO_ROS_ENVIRONMENT"  # set in the environment of the processes bev-mdo starts


def ros_environment(ros: Mapping[str, Any], base: Mapping[str, str] | None = None) -> dict[str, str]:
    """The environment a bev_mdo process runs with, from a validated `ros:` section."""
    env = dict(os.environ if base is None else base)
    env[LAUNCHED] = "1"  # a node executable started with it keeps it (ros/run.py does not apply its config's)
    env.pop("ROS_LOCALHOST_ONLY", None)  # deprecated; it would override the range settings
    env["ROS_DOMAIN_ID"] = str(ros["domain_id"])
    env.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
    env.pop("ROS_STATIC_PEERS", None)
    env.pop("ROS_DISCOVERY_SERVER", None)
    mode = ros["discovery"]
    # bev_mdo's profile, with the initial peers of the domain on one host (a profile the user names wins)
    profile = env.get("FASTRTPS_DEFAULT_PROFILES_FILE", "")
    if "FASTDDS_DEFAULT_PROFILES_FILE" not in env and (not profile or profile == str(DDS_PROFILE)
                                                      or profile.startswith(str(_PROFILE_DIR))):
        env["FASTRTPS_DEFAULT_PROFILES_FILE"] = str(localhost_peers_profile(int(ros["domain_id"])) if mode in (
            "localhost", "static_peers") else DDS_PROFILE)
    if mode == "localhost":
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    elif mode == "static_peers":
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
        env["ROS_STATIC_PEERS"] = ";".join(str(p) for p in ros["static_peers"])
    elif mode == "server":
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
        env["ROS_DISCOVERY_SERVER"] = str(ros["discovery_server"])
    else:  # subnet: explicit opt-in to multicast discovery on the local network
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SUBNET"
    return env


# bev_mdo's Fast DDS profile (its reasons are in the file): the default bev_mdo.ros sets on import
DDS_PROFILE = Path(__file__).resolve().parent / "data" / "fastdds_profile.xml"
# With the LOCALHOST range, rmw_fastrtps announces a participant to 127.0.0.1 at the discovery ports of
# participant ids 0-31 only (maxInitialPeersRange = 32): two processes of one domain whose ids are both 32
# or more never discover each other (measured: of 40 processes, ids 32-40 each saw 32 of the 40 nodes).
# A process takes the first free id, and Fast DDS tries 100 ids past the first (mutation_tries), so
# the per-domain profile below adds 127.0.0.1 at the ports of ids 32-119 as initial peers, each with
# its port (RTPS 9.6.1.1: 7400 + 250 * domain + 10 + 2 * id; ports past 65535 do not exist).
LOCALHOST_PEER_IDS = range(32, 120)
_PROFILE_DIR = Path(tempfile.gettempdir()) / f"bev_mdo_fastdds_{os.getuid()}"


FASTDDS_DEFAULT_LEASE_S = 20.0  # Fast DDS's participant lease when a profile sets none


def participant_lease_s(env: Mapping[str, str] | None = None) -> float:
    """The participant lease of the Fast DDS profile a process started with `env` (default: this one's)
    reads: the file FASTDDS_/FASTRTPS_DEFAULT_PROFILES_FILE names, else bev_mdo's own; Fast DDS's
    default (20 s) when that profile sets none, is unreadable, or sets an infinite lease."""
    import xml.etree.ElementTree as ET

    env = os.environ if env is None else env
    path = env.get("FASTDDS_DEFAULT_PROFILES_FILE") or env.get("FASTRTPS_DEFAULT_PROFILES_FILE") or str(DDS_PROFILE)
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError):
        return FASTDDS_DEFAULT_LEASE_S
    local = {el: el.tag.rsplit("}", 1)[-1] for el in root.iter()}
    parts = [el for el, tag in local.items() if tag == "participant"]
    part = next((el for el in parts if el.get("is_default_profile") == "true"), parts[0] if parts else None)
    lease = next((el for el in (part.iter() if part is not None else ()) if local[el] == "leaseDuration"), None)
    if lease is None:
        return FASTDDS_DEFAULT_LEASE_S
    fields = {local[el]: (el.text or "").strip() for el in lease}
    try:
        return float(fields.get("sec", 0) or 0) + float(fields.get("nanosec", 0) or 0) / 1e9
    except ValueError:  # DURATION_INFINITY and the like
        return FASTDDS_DEFAULT_LEASE_S


def localhost_peers_profile(domain_id: int) -> Path:
    """bev_mdo's Fast DDS profile (DDS_PROFILE) plus 127.0.0.1 at the discovery ports of participant
    ids 32-119 of `domain_id` as initial peers, so up to about 100 processes of one domain on one
    host all find each other; written once per domain under the temp directory."""
    import xml.etree.ElementTree as ET

    ns = "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"
    ET.register_namespace("", ns)
    root = ET.fromstring(DDS_PROFILE.read_text(encoding="utf-8"))
    builtin = root.find(f"{{{ns}}}participant/{{{ns}}}rtps/{{{ns}}}builtin")
    peers = ET.SubElement(builtin, f"{{{ns}}}initialPeersList")
    base = 7400 + 250 * domain_id + 10
    for i in LOCALHOST_PEER_IDS:
        if base + 2 * i <= 65535:
            udp = ET.SubElement(ET.SubElement(peers, f"{{{ns}}}locator"), f"{{{ns}}}udpv4")
            ET.SubElement(udp, f"{{{ns}}}address").text = "127.0.0.1"
            ET.SubElement(udp, f"{{{ns}}}port").text = str(base + 2 * i)
    text = (f'<?xml version="1.0" encoding="UTF-8"?>\n<!-- {DDS_PROFILE} with initial peers for domain '
            f'{domain_id} (bev_mdo/ros_settings.py, localhost_peers_profile) -->\n' + ET.tostring(root, encoding="unicode"))
    path = _PROFILE_DIR / f"localhost_peers_domain{domain_id}.xml"
    try:
        if path.read_text(encoding="utf-8") == text:
            return path
    except OSError:
        pass
    _PROFILE_DIR.mkdir(mode=0o700, exist_ok=True)
    tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")  # several runs start at once: replaced whole
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)
    return path


def validate_min_rows(setting) -> int | dict[str, int]:
    """``ros.pool_min_rows``: the smallest share a pool's batch is cut into, as one whole number for
    every pool or ``{discipline: rows}``; ValueError (one line) otherwise."""
    def rows(v, where):
        if not isinstance(v, int) or isinstance(v, bool) or not 1 <= v <= 10**6:
            raise ValueError(f"ros.pool_min_rows{where} must be a whole number in [1, 1000000], got {v!r}")
        return v

    if isinstance(setting, dict):
        return {str(k): rows(v, f".{k}") for k, v in setting.items()}
    return rows(setting, "")
