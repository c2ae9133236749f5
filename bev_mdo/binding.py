"""Binding of requests and results to a run and to each discipline's effective configuration.

No rclpy import here (the coordinator, the nodes and the tests share it).

A discipline's *fingerprint* is the first 16 hex digits of SHA-256 over a canonical JSON
serialisation of what decides its answers: its name and class, its options, the numeric
vehicle parameters (after defaults and any ``vehicle.<key>`` node override), the vehicle
choices, the cycle section, the energy model and the bev_mdo version. Numbers are
serialised as ``repr(float(x))``, keys sorted, so the same configuration read from YAML, from
a resolved dict or from the node's overridden copy gives the same bytes.

The binding travels in ``header.frame_id`` of every EvaluationRequest (no new wire field):
``"fp:" + ",".join(name=fingerprint)`` for every discipline the request addresses (one for
a hub-and-spoke request, every discipline of the flow for a data-flow MDA). A node answers
only if its own entry is there and equals its own fingerprint; its result echoes the
request's ``frame_id``, and the coordinator accepts a result only when that echo equals what
it sent. A data-flow consumer uses a source's result only if the echoed map holds its own
fingerprint. With signing (protocol/signing.py) the frame_id is covered by the signature.
"""
from __future__ import annotations

import functools
import hashlib
import json
from typing import Any, Mapping

PREFIX = "fp:"
FINGERPRINT_HEX = 16


def _canon(obj: Any) -> Any:
    """JSON-ready copy with numbers as repr(float) (ints and floats of the same value agree)."""
    if isinstance(obj, Mapping):
        return {str(k): _canon(v) for k, v in sorted(obj.items(), key=lambda kv: str(kv[0]))}
    if isinstance(obj, (list, tuple)):
        return [_canon(v) for v in obj]
    if isinstance(obj, bool) or obj is None or isinstance(obj, str):
        return obj
    if hasattr(obj, "item"):  # numpy scalar
        obj = obj.item()
    if isinstance(obj, (int, float)):
        return repr(float(obj))
    return str(obj)


def effective_config(config: Mapping[str, Any], name: str) -> dict:
    """What decides discipline `name`'s answers under `config` (see the module doc)."""
    from bev_mdo import __version__
    from bev_mdo.config import RunConfig, discipline_entries

    listed = config.entries() if isinstance(config, RunConfig) else discipline_entries(config)
    entries = {e["name"]: e for e in listed}
    if name not in entries:
        raise ValueError(f"no discipline {name!r} in the config; it has {sorted(entries)}")
    vehicle = dict(config.get("vehicle") or {})
    from bev_mdo.models.params import VEHICLE_CHOICES, validate_vehicle, vehicle_choice

    numeric = validate_vehicle(vehicle)
    choices = {k: vehicle_choice(vehicle, k) for k in VEHICLE_CHOICES}
    e = entries[name]
    return {
        "discipline": name,
        "class": e["class"],
        "options": e.get("options") or {},
        "vehicle": {k: float(v) for k, v in numeric.items()},
        "vehicle_choices": choices,
        "cycle": config.get("cycle"),
        "energy_model": config.get("energy_model"),
        "version": __version__,
    }


def canonical_json(effective: Mapping[str, Any]) -> str:
    return json.dumps(_canon(effective), sort_keys=True, separators=(",", ":"))


def fingerprint_of_json(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:FINGERPRINT_HEX]


def fingerprint(config: Mapping[str, Any], name: str) -> tuple[str, str]:
    """(fingerprint, canonical JSON of the effective configuration) of discipline `name`."""
    text = canonical_json(effective_config(config, name))
    return fingerprint_of_json(text), text


def tag(expected: Mapping[str, str], names) -> str:
    """The request frame_id binding `names` to their expected fingerprints."""
    return PREFIX + ",".join(f"{n}={expected[n]}" for n in names)


@functools.lru_cache(maxsize=256)  # a run has a handful of distinct tags; a node parses one per message
def parse_tag(frame_id: str) -> dict[str, str] | None:
    """{discipline: fingerprint} from a frame_id; None if it holds no binding (the dict is shared: read it only)."""
    if not frame_id.startswith(PREFIX):
        return None
    out = {}
    for part in frame_id[len(PREFIX):].split(","):
        name, sep, fp = part.partition("=")
        if not sep:
            return None
        out[name] = fp
    return out


def run_matches(bound_run: str, run_id: str) -> bool:
    """A node bound to `bound_run` serves that run and its derived runs (``<run>-baseline``,
    ``<run>-<topology>``); an unbound node (empty) serves any run."""
    return not bound_run or run_id == bound_run or run_id.startswith(bound_run + "-")


def bound_elsewhere(missing, other_runs: Mapping[str, set], run_id: str) -> str:
    """'' or the sentence naming, of the `missing` disciplines, those whose nodes declared themselves bound to
    other runs only (``other_runs``: discipline -> the run ids they named), for a start-up that gave up."""
    named = [f"{d!r} serves run(s) {sorted(other_runs[d])} only" for d in missing if other_runs.get(d)]
    return (f"; on the domain {', '.join(named)}, not run {run_id!r} (a node started with -p run_id:=R serves "
            "run R and its R-... sub-runs only: start one for this run, or one without run_id)") if named else ""


def difference(expected_json: str, got_json: str, limit: int = 3) -> str:
    """One line naming the keys in which two effective configurations differ."""
    try:
        a, b = json.loads(expected_json), json.loads(got_json)
    except ValueError:
        return "undecodable effective configuration"
    diffs: list[str] = []

    def walk(x, y, path):
        if isinstance(x, dict) and isinstance(y, dict):
            for k in sorted(set(x) | set(y)):
                walk(x.get(k, "<absent>"), y.get(k, "<absent>"), f"{path}.{k}" if path else k)
        elif x != y:
            diffs.append(f"{path}: {str(y)[:40]} (this run: {str(x)[:40]})")

    walk(a, b, "")
    if not diffs:
        return "same effective configuration, different fingerprint"
    more = f" and {len(diffs) - limit} more" if len(diffs) > limit else ""
    return "; ".join(diffs[:limit]) + more


def tag_for(config: Mapping[str, Any], names) -> str:
    """The request frame_id that the nodes of `config` serve for `names` (for tools and tests)."""
    names = list(names)
    return tag({n: fingerprint(config, n)[0] for n in names}, names)


# A share of a pooled batch (pool.py) is addressed to one instance: its entry in the tag reads
# ``name=fingerprint@instance``. Only that instance answers; a node of an older version compares
# the whole entry with its fingerprint and so ignores the share rather than answering it twice.
TARGET_SEP = "@"


def target_tag(name: str, fp: str, instance: str) -> str:
    """The request frame_id binding a share of discipline `name` to `fp` and to one `instance`."""
    return tag({name: f"{fp}{TARGET_SEP}{instance.lstrip('/')}"}, [name])


def split_target(entry: str) -> tuple[str, str]:
    """(fingerprint, target instance or '') of one tag entry."""
    fp, _, target = entry.partition(TARGET_SEP)
    return fp, target


def config_binding(config_yaml: str) -> str:
    """The binding a recorder declares: the fingerprint of the config it stores in the bag (the
    canonical JSON of the parsed YAML), so a coordinator knows the bag holds its config."""
    import yaml

    return fingerprint_of_json(canonical_json(yaml.safe_load(config_yaml) or {}))
