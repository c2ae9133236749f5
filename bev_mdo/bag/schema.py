"""ros2msg schema text, type hashes and QoS YAML, as rosbag2 (Jazzy) writes them into MCAP.

bev_mdo's own messages come from the protocol (the .msg files shipped in the package, and the type
hashes rosbags computes from them, equal to rosidl's); other types (std_msgs/Header, ...) from the
installed ``share/<pkg>/msg/<Type>.msg`` files found through ``AMENT_PREFIX_PATH`` (falling back
to the running interpreter's prefix).
"""
from __future__ import annotations

import json
import os
import re
import sys
from functools import lru_cache
from pathlib import Path

from bev_mdo.bag.errors import BagError
from bev_mdo.protocol import messages

SEPARATOR = "=" * 80
PRIMITIVES = frozenset(
    "bool byte char float32 float64 int8 uint8 int16 uint16 int32 uint32 int64 uint64 "
    "string wstring time duration".split()
)
# rmw's "infinite" duration, as rosbag2 writes it
INFINITE = {"sec": 9223372036, "nsec": 854775807}


def split_type(type_name: str) -> tuple[str, str]:
    """``pkg/msg/Type`` or ``pkg/Type`` -> (pkg, Type)."""
    parts = type_name.split("/")
    if len(parts) == 3 and parts[1] == "msg":
        return parts[0], parts[2]
    if len(parts) == 2:
        return parts[0], parts[1]
    raise BagError(f"{type_name!r} is not a message type name (expected pkg/msg/Type)")


def share_file(type_name: str, suffix: str) -> Path:
    """The installed ``share/<pkg>/msg/<Type><suffix>`` file of a message type."""
    pkg, name = split_type(type_name)
    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p] + [sys.prefix]
    for prefix in map(Path, prefixes):
        path = prefix / "share" / pkg / "msg" / f"{name}{suffix}"
        if path.is_file():
            return path
    raise BagError(f"no installed definition of {type_name} (share/{pkg}/msg/{name}{suffix}) "
                   "under AMENT_PREFIX_PATH")


@lru_cache(maxsize=None)
def msg_text(type_name: str) -> str:
    """The .msg text of a type, unchanged."""
    pkg, name = split_type(type_name)
    if pkg == messages.PACKAGE:
        return messages.msg_text(name)
    return share_file(type_name, ".msg").read_text(encoding="utf-8")


def dependencies(type_name: str) -> set[str]:
    """Direct dependencies of a type as ``pkg/Type`` names."""
    pkg, _ = split_type(type_name)
    deps = set()
    for line in msg_text(type_name).splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        field_type = line.split()[0]
        base = re.sub(r"\[.*?\]$", "", field_type)
        base = re.sub(r"<=\d+$", "", base)
        if base in PRIMITIVES:
            continue
        if "/" not in base:
            base = "std_msgs/Header" if base == "Header" else f"{pkg}/{base}"
        deps.add("/".join(split_type(base)))
    return deps


def full_definition(type_name: str) -> str:
    """Schema data: root text then each dependency (sorted, depth first) after a separator."""
    seen: set[str] = set()

    def walk(name: str) -> str:
        out = msg_text(name)
        for dep in sorted(dependencies(name)):
            if dep not in seen:
                seen.add(dep)
                out += f"\n{SEPARATOR}\nMSG: {dep}\n" + walk(dep)
        return out

    return walk(type_name)


@lru_cache(maxsize=None)
def type_hash(type_name: str) -> str:
    """``RIHS01_...`` hash of a type: of bev_mdo's own from the protocol, of another from its
    installed type-description JSON ('' if absent)."""
    pkg, name = split_type(type_name)
    if pkg == messages.PACKAGE:
        return messages.STORE.hash_rihs01(messages.type_name(name))
    try:
        data = json.loads(share_file(type_name, ".json").read_text(encoding="utf-8"))
    except (BagError, ValueError):
        return ""
    for entry in data.get("type_hashes", []):
        if entry.get("type_name") == f"{pkg}/msg/{name}":
            return str(entry.get("hash_string", ""))
    return ""


def qos_dict(*, depth: int = 1000, reliability: str = "reliable", durability: str = "volatile",
             history: str = "keep_last") -> dict:
    """One offered QoS profile in rosbag2 v9 form (enum names in lower case)."""
    return {
        "history": history, "depth": int(depth), "reliability": reliability,
        "durability": durability, "deadline": dict(INFINITE), "lifespan": dict(INFINITE),
        "liveliness": "automatic", "liveliness_lease_duration": dict(INFINITE),
        "avoid_ros_namespace_conventions": False,
    }


def qos_from_rclpy(profile) -> dict:
    """QoS dict from an rclpy QoSProfile (duck-typed, so no rclpy import here)."""
    def enum_name(value, default):
        name = getattr(value, "name", None)
        return name.lower() if name else default

    return qos_dict(
        depth=getattr(profile, "depth", 0) or 0,
        reliability=enum_name(getattr(profile, "reliability", None), "reliable"),
        durability=enum_name(getattr(profile, "durability", None), "volatile"),
        history=enum_name(getattr(profile, "history", None), "keep_last"),
    )
