"""rosbag2 (version 9, Jazzy) bag metadata: ``metadata.yaml`` and the ``rosbag2`` MCAP record."""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import yaml

ROSBAG2_VERSION = 9


@dataclass
class TopicInfo:
    """One recorded topic as rosbag2 describes it."""

    name: str
    type: str
    qos_profiles: list[dict] = field(default_factory=list)
    type_hash: str = ""
    message_count: int = 0


def qos_yaml(profiles: list[dict]) -> str:
    """The ``offered_qos_profiles`` channel-metadata string (a YAML list)."""
    return yaml.safe_dump(profiles, default_flow_style=False, sort_keys=False) if profiles else ""


def bag_info(file_name: str, topics: list[TopicInfo], start_ns: int, end_ns: int) -> dict:
    """The ``rosbag2_bagfile_information`` mapping for one storage file."""
    count = sum(t.message_count for t in topics)
    start_ns = start_ns if count else 0
    duration_ns = max(0, end_ns - start_ns) if count else 0
    return {
        "version": ROSBAG2_VERSION,
        "storage_identifier": "mcap",
        "duration": {"nanoseconds": duration_ns},
        "starting_time": {"nanoseconds_since_epoch": start_ns},
        "message_count": count,
        "topics_with_message_count": [
            {
                "topic_metadata": {
                    "name": t.name,
                    "type": t.type,
                    "serialization_format": "cdr",
                    "offered_qos_profiles": t.qos_profiles,
                    "type_description_hash": t.type_hash,
                },
                "message_count": t.message_count,
            }
            for t in topics
        ],
        "compression_format": "",
        "compression_mode": "",
        "relative_file_paths": [file_name],
        "files": [
            {
                "path": file_name,
                "starting_time": {"nanoseconds_since_epoch": start_ns},
                "duration": {"nanoseconds": duration_ns},
                "message_count": count,
            }
        ],
        "custom_data": None,
        "ros_distro": "jazzy",
    }


def serialized(info: dict) -> str:
    """YAML text for the ``rosbag2`` record's ``serialized_metadata`` key."""
    return yaml.safe_dump(info, default_flow_style=False, sort_keys=False).strip()


def write_metadata_yaml(bag_dir: Path, info: dict) -> None:
    """Write ``<bag_dir>/metadata.yaml`` atomically."""
    path = Path(bag_dir) / "metadata.yaml"
    tmp = path.with_suffix(".yaml.tmp")
    try:
        tmp.write_text(yaml.safe_dump({"rosbag2_bagfile_information": info},
                                      default_flow_style=False, sort_keys=False), encoding="utf-8")
        os.replace(tmp, path)
    finally:  # a failed write (a full disk) leaves no partial file
        tmp.unlink(missing_ok=True)
