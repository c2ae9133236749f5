"""Read bev_mdo bags (a rosbag2 bag directory or a bare .mcap), tolerating truncation.

The file is read sequentially (mcap's StreamReader), so a bag whose writer was killed
yields everything up to its last complete chunk; ``Bag.truncated`` and ``Bag.recovered``
say so. A file whose footer is not followed by exactly the closing magic bytes (cut a few bytes
short, or with bytes appended) is damaged the same way: other readers (rosbags, mcap's indexed
reader) refuse it, so it is reported and ``bev-mdo bag repair`` rewrites it. Anything that is not
a usable bev_mdo bag raises :class:`BagError`.
"""
from __future__ import annotations

import io
import struct
import zlib
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Iterable, Iterator

import yaml
from mcap.exceptions import EndOfFile
from mcap.opcode import Opcode
from mcap.data_stream import ReadDataStream, RecordBuilder
from mcap.records import Attachment, Channel, DataEnd, Footer, Message, Metadata, Schema, Statistics
from mcap.stream_reader import CRCValidationError, StreamReader

from bev_mdo.bag.errors import BagError
from bev_mdo.bag.stored import StoredConfig

MAGIC = b"\x89MCAP0\r\n"
PACKAGE = "bev_mdo_msgs"
METADATA_NAME = "bev_mdo"
KINDS = {Opcode.HEADER: "header", Opcode.CHUNK: "chunk", Opcode.METADATA: "metadata record",
         Opcode.ATTACHMENT: "attachment"}  # named in errors


@dataclass(frozen=True)
class BagMessage:
    """One recorded message (CDR bytes) with its topic, type and times (ns)."""

    topic: str
    type_name: str
    log_time_ns: int
    publish_time_ns: int
    sequence: int
    data: bytes
    channel_id: int


def holds_bag(directory) -> bool:
    """Whether a bag was written in `directory`: its metadata.yaml or an .mcap file (a run stopped before
    its recorder started leaves the nodes' logs/ only)."""
    d = Path(directory)
    return (d / "metadata.yaml").exists() or any(d.glob("*.mcap"))


def find_mcap(path, *, repairing: bool = False) -> Path:
    """The storage file of a bag, the one resolver of every command that reads a bag: the bag's
    directory (the one file its metadata.yaml's ``relative_file_paths`` names, else its one .mcap file),
    its .mcap file itself, or a run's output folder (pareto's or sweep's ``--out``) holding no .mcap
    file but exactly one subfolder that does (``bag/``). A folder of several files, or whose metadata.yaml
    names a file not there, is refused: one of them would be read and the others ignored without a word
    (``repairing``: `bag repair`, which rewrites metadata.yaml, takes the folder's one .mcap file then)."""
    path = Path(path)
    if not path.exists():
        raise BagError(f"{path}: no such file or directory")
    if not path.is_dir():  # a file, or a device such as /dev/null: its header says whether it is a bag
        return path
    files = sorted(path.glob("*.mcap"))  # (`bag repair`'s backups are .mcap.bak: not counted)
    held = f"{len(files)} .mcap file{'s' if len(files) != 1 else ''} ({', '.join(f.name for f in files)})"
    named = storage_files(path)
    missing = [n for n in named if Path(n).name != n or not (path / n).is_file()]
    if missing and not repairing:
        raise BagError(f"{path}: its metadata.yaml names {', '.join(missing)}, not in the folder; it holds "
                       + (f"{held}: give the .mcap file to read" if files else "no .mcap file")
                       + (" (or `bev-mdo bag repair` it: that rewrites metadata.yaml)" if len(files) == 1 else ""))
    if named and not missing:
        if len(named) > 1:
            raise BagError(f"{path}: its metadata.yaml names {len(named)} storage files ({', '.join(named)}; a "
                           "split bag): give the one to read")
        return path / named[0]
    if len(files) > 1:
        raise BagError(f"{path}: holds {held}: give the one to read")
    if not files:
        inside = sorted(d for d in path.iterdir() if d.is_dir() and any(d.glob("*.mcap")))
        if len(inside) == 1:
            return find_mcap(inside[0], repairing=repairing)
        raise BagError(f"{path}: holds no .mcap file" + (
            f" but {len(inside)} bags ({', '.join(d.name for d in inside)}): name one" if inside else
            " (give a bag directory, its .mcap file or a run's output folder with one bag in it)"))
    return files[0]


def bagfile_information(bag_dir: Path) -> dict:
    """A bag directory's metadata.yaml, its ``rosbag2_bagfile_information`` mapping; {} without a readable one
    (a bag being written has none yet; `bag repair` writes it)."""
    return _bagfile_information(bag_dir)[0]


def _bagfile_information(bag_dir: Path) -> tuple[dict, str]:
    """(:func:`bagfile_information`, why a metadata.yaml there is of no use: '' when it is, or there is none)."""
    path = Path(bag_dir) / "metadata.yaml"
    if not path.exists():
        return {}, ""
    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        return {}, f"cannot be read ({getattr(exc, 'strerror', None) or type(exc).__name__})"
    except yaml.YAMLError:
        return {}, "is not valid YAML"
    info = doc.get("rosbag2_bagfile_information") if isinstance(doc, dict) else None
    if not isinstance(info, dict):
        return {}, "holds no rosbag2_bagfile_information mapping"
    return info, "" if isinstance(info.get("relative_file_paths"), list) else "names no storage file"


def storage_files(bag_dir: Path) -> list[str]:
    """The storage files a bag directory's metadata.yaml names (rosbag2's ``relative_file_paths``, relative to
    the directory); [] without a readable one or where it is not a list."""
    names = bagfile_information(bag_dir).get("relative_file_paths")
    return [str(n) for n in names] if isinstance(names, list) else []


class Bag:
    """An opened bag: schemas, channels, metadata and attachments; messages on demand."""

    def __init__(self, path, *, strict: bool = True, salvage: bool = False):
        self.path = Path(path)
        self.salvage = salvage  # `bag repair`: a damaged chunk is skipped, not the end of what is read
        self.skipped: list[tuple[int, int, str | None]] = []  # (start, end, KINDS name) of each record left out
        self.mcap_path = find_mcap(self.path, repairing=salvage)
        self.bag_dir = self.mcap_path.parent
        self.strict = strict
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}
        self.metadata: dict[str, dict[str, str]] = {}
        self.attachments: dict[str, bytes] = {}
        self.counts: dict[str, int] = {}
        self.truncated = False  # read in part, or damaged: `bag repair` rewrites it (``damage`` says what)
        self.end_damage = ""  # what is wrong with the end of a file whose records are all there
        self.damaged_attachments: list[str] = []
        self.data_crc_failed = False
        self.summary_ok = False  # a summary that passed its CRC check (its channels fill in a damaged chunk's)
        self._written_count: int | None = None  # the summary's Statistics message count
        self.recovered_bytes = 0
        self.start_ns = 0
        self.end_ns = 0
        self._decoders: dict[int, object] = {}
        self._scan()

    # -- scanning ------------------------------------------------------------------------
    def _check_magic(self) -> None:
        try:
            with open(self.mcap_path, "rb") as f:
                head = f.read(len(MAGIC))
        except OSError as exc:
            raise BagError(f"{self.mcap_path}: cannot read ({exc.strerror})") from exc
        if not head:
            raise BagError(f"{self.mcap_path}: empty file, not an MCAP bag")
        if head != MAGIC[: len(head)]:
            raise BagError(f"{self.mcap_path}: not an MCAP file (bad magic bytes)")
        if len(head) < len(MAGIC):
            raise BagError(f"{self.mcap_path}: truncated MCAP header")

    def _records(self) -> Iterator[object]:
        """All records in file order; sets ``truncated`` when the file ends early."""
        with open(self.mcap_path, "rb") as f:
            data_ended = False  # past DataEnd: only the summary (copies and indexes) is left
            skipped, at, done = [], None, len(MAGIC)  # done: where the last record read ends (in this pass)
            while True:
                reader = StreamReader(f, skip_magic=at is not None, validate_crcs=True)
                try:
                    for record in reader.records:
                        self.recovered_bytes = done = f.tell()
                        data_ended = data_ended or isinstance(record, DataEnd)
                        yield record
                except Exception as exc:  # noqa: BLE001 - a short read; zstd, struct, decode errors of damaged bytes
                    start = max(done, at or 0)  # where the record that failed begins
                    declared = self._declared_end(start)  # where its own length says it ends (None: past the file)
                    short = isinstance(exc, (EndOfFile, struct.error))
                    if short and (data_ended or declared is None):  # the file ends early (or a summary length is bad)
                        self.truncated = True
                        if data_ended:
                            self.end_damage = "truncated or damaged in the summary after the messages"
                        break
                    if isinstance(exc, CRCValidationError) and isinstance(exc.record, DataEnd):
                        # every chunk passed its own check: a record between them (metadata, attachment) is damaged
                        self.truncated = self.data_crc_failed = True
                        at = self.recovered_bytes = done = f.tell()
                        data_ended = True
                        yield exc.record
                        continue  # on to the summary, read as before
                    # read past its own end: a length inside the record (a string's, in the header) is damaged
                    past = declared is not None and (short or f.tell() > declared)
                    end = declared if declared is not None else f.tell()
                    kind = KINDS.get(self._opcode(start)) if end > start else None
                    if not data_ended and self.salvage and end > start:
                        at = end  # past the damaged record (a chunk is read whole before it is checked)
                        f.seek(at)
                        skipped.append((start, at, kind))
                        self.truncated, self.skipped = True, skipped
                        continue  # the records after it, each checked as before
                    if not data_ended:
                        why = ("its CRC check fails" if isinstance(exc, CRCValidationError) else
                               "a length field inside it points past the record" if past else "it cannot be read")
                        what = f"the {kind} at bytes {start}-{end} is damaged ({why})" if kind else \
                            f"the record after byte {start} cannot be read"
                        raise BagError(f"{self.mcap_path}: corrupt MCAP data: {what}; run `bev-mdo bag repair` to keep "
                                       f"the records {'before and ' * (start > len(MAGIC))}after it") from exc
                    self.truncated = True  # every message was read: noted, and `bag repair` rewrites the summary
                    self.end_damage = "damaged in the summary after the messages (a record cannot be read)"
                break

    def _declared_end(self, start: int) -> int | None:
        """Where the record at byte `start` ends by its own length field (opcode, uint64 length), None past the file."""
        with open(self.mcap_path, "rb") as f:
            f.seek(start)
            head = f.read(9)
        end = start + 9 + ReadDataStream(io.BytesIO(head[1:])).read8() if len(head) == 9 else None  # MCAP framing
        return end if end is not None and end <= self.file_size else None

    def _opcode(self, at: int) -> int:
        with open(self.mcap_path, "rb") as f:
            f.seek(at)
            return f.read(1)[0]

    def _scan(self) -> None:
        self._check_magic()
        saw_header = summary = False
        per_channel: dict[int, int] = {}
        copies: dict[type, dict[int, object]] = {Schema: {}, Channel: {}}  # the summary's
        for record in self._records():
            saw_header = True
            if isinstance(record, DataEnd):
                summary = True  # its schemas and channels repeat the data section's: those are the ones read
            elif summary and isinstance(record, (Schema, Channel)):
                copies[type(record)][record.id] = record
            elif summary and isinstance(record, Statistics):
                self._written_count = record.message_count
            elif isinstance(record, Schema):
                if record.encoding != "ros2msg":
                    raise BagError(f"{self.mcap_path}: schema {record.name!r} has encoding "
                                   f"{record.encoding!r}, expected 'ros2msg'")
                self.schemas[record.id] = record
            elif isinstance(record, Channel):
                self.channels[record.id] = record
            elif isinstance(record, Metadata):
                self.metadata[record.name] = dict(record.metadata)
            elif isinstance(record, Attachment):
                if self._intact(record, self.recovered_bytes):
                    self.attachments[record.name] = bytes(record.data)
                else:
                    self.damaged_attachments.append(record.name)
                    self.truncated = True
            elif isinstance(record, Message):
                self.start_ns = min(self.start_ns, record.log_time) if per_channel else record.log_time
                per_channel[record.channel_id] = per_channel.get(record.channel_id, 0) + 1
                self.end_ns = max(self.end_ns, record.log_time)
            elif isinstance(record, Footer):
                self._check_end(self.recovered_bytes)
                self._check_summary(record, self.recovered_bytes)
                break
        if not saw_header:
            raise BagError(f"{self.mcap_path}: truncated MCAP header")
        if self.truncated and not self.channels and not self.metadata:
            raise BagError(f"{self.mcap_path}: truncated, no complete record after the header")
        if self.summary_ok:  # a channel (or schema) whose record was in a damaged chunk: the summary's copy
            for kind, known in ((Schema, self.schemas), (Channel, self.channels)):
                for rid, record in copies[kind].items():
                    known.setdefault(rid, record)
        else:
            self._written_count = None
        for channel_id, n in per_channel.items():
            topic = self._channel(channel_id).topic
            self.counts[topic] = self.counts.get(topic, 0) + n
        # A bev_mdo recording holds our schemas; other packages' topics may be recorded beside
        # them (the recorder takes any topic it is given), but a bag of only foreign types is not ours.
        # A file of no schema is ours only with bev_mdo's run record (a run that recorded no message yet).
        foreign = [s.name for s in self.schemas.values() if not s.name.startswith(PACKAGE + "/")]
        if self.strict and len(foreign) == len(self.schemas) and (foreign or METADATA_NAME not in self.metadata):
            raise BagError(f"{self.mcap_path}: " + (f"schema {foreign[0]} is not a {PACKAGE} type (not a bev_mdo "
                           "recording)" if foreign else f"holds no bev_mdo run (no {PACKAGE} topic, no run record)"))
        for channel in self.channels.values():
            self.counts.setdefault(channel.topic, 0)
            if channel.message_encoding != "cdr":
                raise BagError(f"{self.mcap_path}: topic {channel.topic} has message encoding "
                               f"{channel.message_encoding!r}, expected 'cdr'")

    def _check_end(self, footer_end: int) -> None:
        """After the footer a complete file holds the magic bytes and nothing more."""
        try:
            with open(self.mcap_path, "rb") as f:
                f.seek(footer_end)
                tail = f.read(len(MAGIC) + 1)
        except OSError as exc:
            raise BagError(f"{self.mcap_path}: cannot read ({exc.strerror})") from exc
        if tail == MAGIC:
            return
        if len(tail) > len(MAGIC) and tail[:len(MAGIC)] == MAGIC:
            extra = self.file_size - footer_end - len(MAGIC)
            self.end_damage = f"{extra} byte(s) after the end of the MCAP data"
        elif len(tail) < len(MAGIC) and MAGIC.startswith(tail):
            self.end_damage = f"truncated: the closing magic bytes are cut short ({len(tail)} of {len(MAGIC)})"
        else:
            self.end_damage = "the closing magic bytes after the footer are invalid"
        self.truncated = True

    def _check_summary(self, footer: Footer, footer_end: int) -> None:
        """The summary section's CRC (the footer's ``summary_crc``, over the summary and the footer up to it):
        the mcap library does not check it, and its schemas, channels and indexes are what other readers use."""
        if not footer.summary_start or not footer.summary_crc:
            self.summary_ok = bool(footer.summary_start)  # a summary written without its CRC: taken as it is
            return
        with open(self.mcap_path, "rb") as f:
            f.seek(footer.summary_start)
            self.summary_ok = zlib.crc32(f.read(footer_end - 4 - footer.summary_start)) == footer.summary_crc
        if not self.summary_ok:
            self.truncated = True
            self.end_damage = self.end_damage or "damaged in the summary after the messages (its CRC check fails)"

    def _intact(self, attachment: Attachment, end: int) -> bool:
        """Whether an attachment (ending at byte ``end``) passes its CRC check, which the mcap library skips: its
        record as the library writes it again, CRC included, against the file's bytes (a stored CRC 0: unchecked)."""
        builder = RecordBuilder()
        attachment.write(builder)
        record = bytes(builder.end())
        with open(self.mcap_path, "rb") as f:
            f.seek(max(0, end - len(record)))
            stored = f.read(len(record))
        return stored[:-4] != record[:-4] or stored[-4:] in (record[-4:], bytes(4))  # (padded: cannot tell)

    @property
    def damage(self) -> str:
        """What is wrong with a file whose messages were read (chunks left out, a damaged attachment, summary or
        end), '' when nothing is or the file is merely cut short."""
        parts = []
        if self.skipped:
            chunks = all(kind == "chunk" for _a, _b, kind in self.skipped)
            parts.append(f"{len(self.skipped)} damaged {'chunk' if chunks else 'record'}(s) left out (bytes "
                         + ", ".join(f"{a}-{b}" + (f": the {kind}" if not chunks and kind else "")
                                     for a, b, kind in self.skipped) + ")")
        if self.damaged_attachments:
            parts.append(f"attachment {', '.join(self.damaged_attachments)} damaged (its CRC check fails; left out)")
        elif self.data_crc_failed:
            parts.append("a metadata record between the chunks is damaged (the data section's CRC check fails)")
        return "; ".join(parts + [self.end_damage] if self.end_damage else parts)

    @property
    def written_count(self) -> int | None:
        """How many messages the bag was written with, where its intact summary or the metadata.yaml that names
        it says so and that is not fewer than were read (None otherwise)."""
        count = self._written_count
        if count is None and self.mcap_path.name in storage_files(self.bag_dir):
            count = bagfile_information(self.bag_dir).get("message_count")
        return count if isinstance(count, int) and count >= self.message_count else None

    def _channel(self, channel_id: int) -> Channel:
        try:
            return self.channels[channel_id]
        except KeyError:
            raise BagError(f"{self.mcap_path}: message on unknown channel {channel_id}") from None

    # -- public ----------------------------------------------------------------------------
    @property
    def topics(self) -> dict[str, str]:
        """topic -> ``pkg/msg/Type``."""
        return {c.topic: self.schemas[c.schema_id].name for c in self.channels.values()
                if c.schema_id in self.schemas}

    @property
    def message_count(self) -> int:
        return sum(self.counts.values())

    @property
    def file_size(self) -> int:
        return self.mcap_path.stat().st_size

    @property
    def duration_ns(self) -> int:
        return max(0, self.end_ns - self.start_ns)

    @property
    def info(self) -> dict[str, str]:
        """The ``bev_mdo`` metadata record (config_yaml, version, run_id, ...)."""
        return dict(self.metadata.get(METADATA_NAME, {}))

    @cached_property
    def stored_config(self) -> StoredConfig:
        """The run's configuration stored in the bag (``read_config``), parsed once for every reader."""
        return StoredConfig.parse(read_config(self))

    def messages(self, topics: Iterable[str] | None = None) -> Iterator[BagMessage]:
        """Recorded messages in file order (per-topic order is recording order); ``topics`` None
        means every topic, an empty list none."""
        wanted = set(topics) if topics is not None else None
        for record in self._records():
            if isinstance(record, Message):
                channel = self._channel(record.channel_id)
                if wanted is not None and channel.topic not in wanted:
                    continue
                yield BagMessage(channel.topic, self.schemas[channel.schema_id].name,
                                 record.log_time, record.publish_time, record.sequence,
                                 bytes(record.data), record.channel_id)
            elif isinstance(record, Footer):
                return

    def decode(self, message: BagMessage):
        """Decode one message: bev_mdo's own with the protocol's generated codec when the bag's schema
        is the protocol's definition, any other with mcap-ros2-support from the bag's schema (a dynamic
        object). No ROS needed either way."""
        decoder = self._decoders.get(message.channel_id)
        if decoder is None:
            decoder = self._decoders[message.channel_id] = self._decoder(message.channel_id)
        try:
            return decoder(message.data)
        except Exception as exc:
            raise BagError(f"{self.mcap_path}: cannot decode a {message.type_name} message on "
                           f"{message.topic} ({type(exc).__name__})") from exc

    def _decoder(self, channel_id: int):
        from bev_mdo.bag.schema import full_definition
        from bev_mdo.protocol import messages

        schema = self.schemas[self.channels[channel_id].schema_id]
        if schema.name.split("/")[0] == messages.PACKAGE:
            try:
                same = full_definition(schema.name) == schema.data.decode("utf-8")
            except (BagError, UnicodeDecodeError):
                same = False
            if same:
                return lambda data, name=schema.name: messages.decode(data, name)
        from mcap_ros2.decoder import DecoderFactory

        decoder = DecoderFactory().decoder_for("cdr", schema)
        if decoder is None:
            raise BagError(f"{self.mcap_path}: cannot decode {schema.name}")
        return decoder

    def decoded(self, topics: Iterable[str] | None = None) -> Iterator[tuple[BagMessage, object]]:
        """(message, decoded object) pairs in file order."""
        for message in self.messages(topics):
            yield message, self.decode(message)

    @property
    def metadata_note(self) -> str:
        """One line when the bag's folder holds a metadata.yaml of no use ('' otherwise): it is ignored, and said
        so, for the bag is read from its .mcap file."""
        why = _bagfile_information(self.bag_dir)[1]
        return (f"{self.bag_dir / 'metadata.yaml'} {why}: ignored, the bag is read from {self.mcap_path.name} "
                "(`bev-mdo bag repair` writes it again)") if why else ""

    def recovery_note(self) -> str:
        """One line saying how much of a truncated file was read ('' when complete)."""
        if not self.truncated:
            return ""
        return (f"{self.mcap_path}: {self.damage or 'truncated'}; read {self.count_phrase} from the first "
                f"{self.recovered_bytes} of {self.file_size} bytes (run `bev-mdo bag repair`)")

    @property
    def count_phrase(self) -> str:
        """'206 of 232 messages' where the number written is known, else '206 messages'."""
        total = self.written_count
        return f"{self.message_count}{f' of {total}' if total is not None else ''} messages"


def open_bag(path, *, strict: bool = True, salvage: bool = False) -> Bag:
    """Open a bag directory or a bare .mcap file; ``strict`` rejects non-bev_mdo schemas; ``salvage``
    (for ``bag repair``) reads on past a damaged chunk."""
    return Bag(path, strict=strict, salvage=salvage)


def read_config(bag) -> str:
    """The run's resolved configuration (YAML text) stored in the bag ('' if none)."""
    bag = bag if isinstance(bag, Bag) else open_bag(bag)
    text = bag.info.get("config_yaml")
    if text is None and "config.yaml" in bag.attachments:
        text = bag.attachments["config.yaml"].decode("utf-8")
    return text or ""
