"""Write rosbag2-compatible MCAP bags: ``<bag>/metadata.yaml`` + ``<bag>/<name>_0.mcap``.

Chunked and zstd-compressed; a killed writer loses at most the chunk in progress
(``flush()`` closes the current chunk early; the recorder calls it periodically).
"""
from __future__ import annotations

import time
from pathlib import Path

from mcap.writer import CompressionType, Writer

from bev_mdo import __version__
from bev_mdo.bag import metadata as meta
from bev_mdo.bag import schema
from bev_mdo.bag.errors import BagError
from bev_mdo.bag.signing import SIGNING_METADATA, keep_run_key, state

PROFILE = "ros2"
METADATA_NAME = "bev_mdo"  # MCAP metadata record holding config_yaml, version, run_id, ...
CONFIG_ATTACHMENT = "config.yaml"
CHUNK_SIZE_BYTES = 256 * 1024  # uncompressed; modest so a crash loses little


class BagWriter:
    """One rosbag2 bag directory with a single MCAP storage file.

    ``metadata`` (str -> str; e.g. ``config_yaml``, ``run_id``) is written at once as the
    ``bev_mdo`` MCAP metadata record, with ``version`` added; ``config_yaml`` is also
    attached as ``config.yaml``. Use as a context manager or call ``close()``.
    """

    def __init__(self, bag_dir, *, metadata: dict[str, str] | None = None,
                 chunk_size_bytes: int = CHUNK_SIZE_BYTES):
        self.bag_dir = Path(bag_dir)
        self.file_name = f"{self.bag_dir.name}_0.mcap"
        self.path = self.bag_dir / self.file_name
        if self.path.exists() or (self.bag_dir / "metadata.yaml").exists():
            raise BagError(f"{self.bag_dir}: bag already exists")
        others = sorted(p.name for p in self.bag_dir.glob("*.mcap")) if self.bag_dir.is_dir() else []
        if others:  # a bag without metadata.yaml (a killed recorder's): one metadata could not describe both
            raise BagError(f"{self.bag_dir}: holds {', '.join(others)} already (a truncated bag? "
                           "`bev-mdo bag repair` it); choose another directory")
        try:
            self.bag_dir.mkdir(parents=True, exist_ok=True)
            self._stream = open(self.path, "xb")
        except OSError as exc:  # a file where a folder of the path should be, no permission, ...
            raise BagError(f"{self.bag_dir}: cannot create the bag ({exc.strerror or exc})") from None
        self._mcap = mcap_writer(self._stream, f"bev_mdo {__version__} (mcap python)", chunk_size_bytes)
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._topics: dict[str, meta.TopicInfo] = {}
        self._start_ns: int | None = None
        self._end_ns = 0
        self.closed = False
        self.metadata = {"version": __version__, **(metadata or {})}
        self._mcap.add_metadata(METADATA_NAME, {k: str(v) for k, v in self.metadata.items()})
        if "config_yaml" in self.metadata:  # a run's bag: its signing state, under the run's key
            self._mcap.add_metadata(SIGNING_METADATA, state(self.metadata["config_yaml"],
                                                            str(self.metadata.get("run_id", ""))))
            keep_run_key(self.bag_dir, self.metadata["config_yaml"])  # where readers find the key: outside the bag
            now = time.time_ns()
            self._mcap.add_attachment(now, now, CONFIG_ATTACHMENT, "application/yaml",
                                      self.metadata["config_yaml"].encode("utf-8"))
        self._stream.flush()

    # -- topics and messages -------------------------------------------------------------
    def add_topic(self, topic: str, type_name: str, qos=None, type_hash: str | None = None) -> int:
        """Register a topic (idempotent); ``qos``: dict, list of dicts or rclpy QoSProfile."""
        if topic in self._channels:
            return self._channels[topic]
        pkg, name = schema.split_type(type_name)
        full_type = f"{pkg}/msg/{name}"
        if full_type not in self._schemas:
            text = schema.full_definition(full_type)
            self._schemas[full_type] = self._mcap.register_schema(
                full_type, "ros2msg", text.encode("utf-8"))
        profiles = _qos_list(qos)
        digest = type_hash or schema.type_hash(full_type)
        channel_id = self._mcap.register_channel(
            topic, "cdr", self._schemas[full_type],
            {"offered_qos_profiles": meta.qos_yaml(profiles), "topic_type_hash": digest},
        )
        self._channels[topic] = channel_id
        self._topics[topic] = meta.TopicInfo(topic, full_type, profiles, digest)
        return channel_id

    def write(self, topic: str, cdr: bytes, log_time_ns: int, publish_time_ns: int | None = None,
              sequence: int = 0) -> None:
        """Append one serialized (CDR) message on a registered topic."""
        if topic not in self._channels:
            raise BagError(f"{self.path}: topic {topic} was not added")
        self._mcap.add_message(self._channels[topic], int(log_time_ns), bytes(cdr),
                               int(publish_time_ns if publish_time_ns is not None else log_time_ns),
                               sequence=int(sequence) & 0xFFFFFFFF)
        self._topics[topic].message_count += 1
        self._start_ns = log_time_ns if self._start_ns is None else min(self._start_ns, log_time_ns)
        self._end_ns = max(self._end_ns, log_time_ns)

    def flush(self) -> None:
        """Close the chunk in progress and push it to the OS (survives a SIGKILL after this)."""
        self._mcap.flush()

    @property
    def message_count(self) -> int:
        return sum(t.message_count for t in self._topics.values())

    def close(self) -> None:
        """Write the ``rosbag2`` record, the MCAP summary and ``metadata.yaml``."""
        if self.closed:
            return
        self.closed = True
        info = meta.bag_info(self.file_name, list(self._topics.values()), self._start_ns or 0, self._end_ns)
        self._mcap.add_metadata("rosbag2", {"serialized_metadata": meta.serialized(info)})
        self._mcap.finish()
        self._stream.close()
        meta.write_metadata_yaml(self.bag_dir, info)

    def abandon(self) -> None:
        """Close the file without its summary, after a write failed (e.g. a full disk): the complete chunks stay
        readable and ``bev-mdo bag repair`` makes the bag whole. Idempotent."""
        self.closed = True
        try:
            self._stream.close()
        except OSError:  # what was still buffered cannot be written either
            pass

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def mcap_writer(stream, library: str, chunk_size_bytes: int = CHUNK_SIZE_BYTES) -> Writer:
    """A started MCAP writer of bev_mdo's bags: ros2 profile, zstd-compressed chunks, the data section's CRC."""
    writer = Writer(stream, chunk_size=chunk_size_bytes, compression=CompressionType.ZSTD,
                    enable_data_crcs=True)  # so a damaged metadata record or attachment is found
    writer.start(profile=PROFILE, library=library)
    return writer


def _qos_list(qos) -> list[dict]:
    if qos is None:
        return [schema.qos_dict()]
    if isinstance(qos, dict):
        return [qos]
    if isinstance(qos, (list, tuple)):
        return [q if isinstance(q, dict) else schema.qos_from_rclpy(q) for q in qos]
    return [schema.qos_from_rclpy(qos)]
