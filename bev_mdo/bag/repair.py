"""Repair a truncated bag: rewrite its readable part with a summary, and a new metadata.yaml.

Schemas (their recorded text), channels (with QoS and type hash), metadata records and
attachments are kept; the original file is kept as ``<file>.bak``. A repair that cannot be written
(a full disk, a read-only folder) is a BagError naming the file and the reason, and leaves the bag
as it was, with no partial file.
"""
from __future__ import annotations

import os
import shutil
from dataclasses import dataclass
from pathlib import Path

import yaml

from bev_mdo.bag import metadata as meta
from bev_mdo.bag.errors import BagError
from bev_mdo.bag.reader import Bag, bagfile_information, open_bag, storage_files
from bev_mdo.bag.writer import mcap_writer


@dataclass
class RepairResult:
    """What ``repair`` did."""

    bag_dir: Path
    mcap_path: Path
    backup_path: Path | None
    message_count: int
    was_truncated: bool
    rewritten: bool
    metadata_written: bool = False  # metadata.yaml was missing or did not describe the bag
    damage: str = ""  # what was damaged (the records left out), when the reader could say
    written_count: int | None = None  # how many messages the bag was written with, where known


def _topic_infos(bag: Bag) -> list[meta.TopicInfo]:
    infos = []
    for channel in bag.channels.values():
        profiles = yaml.safe_load(channel.metadata.get("offered_qos_profiles", "") or "[]") or []
        infos.append(meta.TopicInfo(channel.topic, bag.schemas[channel.schema_id].name, profiles,
                                    channel.metadata.get("topic_type_hash", ""),
                                    bag.counts.get(channel.topic, 0)))
    return infos


def _backup_path(path: Path) -> Path:
    candidate = path.with_name(path.name + ".bak")
    n = 1
    while candidate.exists():
        candidate = path.with_name(f"{path.name}.bak{n}")
        n += 1
    return candidate


def _rewrite(bag: Bag, out: Path, info: dict) -> None:
    with open(out, "wb") as stream:
        writer = mcap_writer(stream, "bev_mdo bag repair (mcap python)")
        for name, data in bag.metadata.items():
            if name != "rosbag2":
                writer.add_metadata(name, data)
        for name, data in bag.attachments.items():
            media = "application/yaml" if name.endswith((".yaml", ".yml")) else "application/octet-stream"
            writer.add_attachment(0, 0, name, media, data)
        schema_ids = {sid: writer.register_schema(s.name, s.encoding, s.data)
                      for sid, s in bag.schemas.items()}
        channel_ids = {cid: writer.register_channel(c.topic, c.message_encoding,
                                                    schema_ids[c.schema_id], dict(c.metadata))
                       for cid, c in bag.channels.items()}
        for msg in bag.messages():
            writer.add_message(channel_ids[msg.channel_id], msg.log_time_ns, msg.data,
                               msg.publish_time_ns, msg.sequence)
        writer.add_metadata("rosbag2", {"serialized_metadata": meta.serialized(info)})
        writer.finish()


def _replace_with_rewrite(bag: Bag, path: Path, info: dict) -> Path:
    """Rewrite the bag beside ``path`` and put it in its place; returns where the original went. An
    interruption or a failure at any step leaves no ``.repairing`` file, and ``path`` always names a whole
    file (the original until the rewritten one atomically replaces it): the backup is a second link to
    the original (a copy where the file system has no hard links), not a rename."""
    tmp = path.with_name(path.name + ".repairing")
    backup = None
    try:
        _rewrite(bag, tmp, info)
        backup = _backup_path(path)
        try:
            os.link(path, backup)
        except OSError:
            shutil.copy2(path, backup)
        os.replace(tmp, path)
        return backup
    except BaseException:
        if backup is not None and tmp.exists():  # not replaced: the backup (a partial copy on a full disk) goes
            backup.unlink(missing_ok=True)
        raise
    finally:
        tmp.unlink(missing_ok=True)


def repair(bag_dir, *, force: bool = False) -> RepairResult:
    """Rebuild summary and metadata.yaml of a (possibly truncated) bag directory or .mcap."""
    bag = open_bag(bag_dir, strict=False, salvage=True)
    path = bag.mcap_path
    info = meta.bag_info(path.name, _topic_infos(bag), bag.start_ns, bag.end_ns)
    good_yaml = _describes(bag.bag_dir, path.name, bag.message_count)
    written = bag.written_count  # (before metadata.yaml is written again)
    if not bag.truncated and good_yaml and not force:
        return RepairResult(bag.bag_dir, path, None, bag.message_count, False, False)
    backup, writing = None, path
    try:
        if bag.truncated or force:
            backup = _replace_with_rewrite(bag, path, info)
        writing = Path(bag.bag_dir) / "metadata.yaml"  # (a folder of that name was blamed on the .mcap)
        meta.write_metadata_yaml(bag.bag_dir, info)
    except OSError as exc:  # a full disk, a read-only folder: one line (exit 2), nothing partial left
        state = (f"the bag is repaired (original kept as {backup}), its metadata.yaml is not" if backup
                 else "the bag is unchanged")
        raise BagError(f"{writing}: the repair could not be written ({exc.strerror or exc}); {state}") from exc
    return RepairResult(bag.bag_dir, path, backup, bag.message_count, bag.truncated,
                        backup is not None, not good_yaml, bag.damage, written)


def _describes(bag_dir: Path, file_name: str, message_count: int) -> bool:
    """Whether ``bag_dir``'s metadata.yaml is this bag's: it names its file and its message count (a
    garbage one, or one naming another file, was taken as 'checked' and rosbags could not open the bag)."""
    if file_name not in storage_files(bag_dir):  # as the reader reads it (a bare string names no file)
        return False
    try:
        return int(bagfile_information(bag_dir).get("message_count")) == message_count
    except (TypeError, ValueError):
        return False
