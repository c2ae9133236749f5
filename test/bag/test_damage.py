"""Truncated, corrupt and foreign bags: complete part readable, repair works, clear errors."""
from __future__ import annotations

import errno
import random
import shutil

import pytest

from .conftest import cli, write_synthetic



def _decoded_iterations(bag):
    return [(m.topic, int(obj.sequence)) for m, obj in bag.decoded()]


@pytest.fixture
def full(tmp_path):
    bag_dir = tmp_path / "full"
    write_synthetic(bag_dir, n_iterations=40, chunk_size_bytes=1500)
    return bag_dir


def test_truncated_file_reads_complete_prefix(full, tmp_path):
    from bev_mdo.bag.reader import open_bag

    complete = open_bag(full)
    reference = _decoded_iterations(complete)
    data = (full / "full_0.mcap").read_bytes()
    last, counts = -1, {}
    for fraction in (0.15, 0.3, 0.5, 0.7, 0.9, 0.99):
        cut = tmp_path / f"cut_{fraction}.mcap"
        cut.write_bytes(data[: int(len(data) * fraction)])
        bag = open_bag(cut)
        assert bag.truncated
        got = _decoded_iterations(bag)
        assert got == reference[: len(got)]            # an exact prefix, values intact
        assert len(got) >= last                         # more file, never fewer messages
        assert bag.message_count == len(got)
        assert "truncated" in bag.recovery_note() and str(cut) in bag.recovery_note()
        last = counts[fraction] = len(got)
    assert 0 < counts[0.15] < counts[0.5] < len(reference)
    assert counts[0.99] == len(reference)  # only the summary section was cut


def test_repair_restores_summary_readable_by_rosbags(full):
    from rosbags.highlevel import AnyReader

    from bev_mdo.bag.reader import open_bag, read_config

    mcap = full / "full_0.mcap"
    data = mcap.read_bytes()
    mcap.write_bytes(data[: int(len(data) * 0.6)])
    (full / "metadata.yaml").unlink()
    recovered = open_bag(full).message_count
    assert 0 < recovered < 200

    code, out, err = cli("bag", "repair", str(full))
    assert code == 0, err
    assert "repaired" in out and (full / "full_0.mcap.bak").is_file()
    bag = open_bag(full)
    assert not bag.truncated and bag.message_count == recovered
    assert read_config(bag).startswith("problem:")
    with AnyReader([full]) as reader:
        assert reader.message_count == recovered
        seqs = [int(reader.deserialize(raw, c.msgtype).sequence) for c, _t, raw in reader.messages()]
    assert seqs == [s for _t, s in _decoded_iterations(open_bag(full / "full_0.mcap.bak"))]
    # a second repair has nothing to do
    code, out, _ = cli("bag", "repair", str(full))
    assert code == 0 and "complete" in out


@pytest.mark.parametrize("text", ["not: [valid", "rosbag2_bagfile_information: {}", None, "bare string"])
def test_a_metadata_yaml_that_does_not_describe_the_bag_is_written_again(full, text):
    """A garbage metadata.yaml, or one naming another file, got 'complete; metadata.yaml checked' and
    stayed, and rosbags could not open the bag. So did one whose relative_file_paths is the file's name as
    a bare string, not a list: repair read metadata.yaml itself (a substring match), where the reader
    (reader.storage_files) finds no file named."""
    from rosbags.highlevel import AnyReader

    from bev_mdo.bag.reader import open_bag

    good = (full / "metadata.yaml").read_text()
    if text == "bare string":
        text = good.replace("relative_file_paths:\n  - full_0.mcap", "relative_file_paths: full_0.mcap")
        assert text != good
    (full / "metadata.yaml").write_text(good.replace("full_0.mcap", "other_0.mcap") if text is None else text)
    code, out, err = cli("bag", "repair", str(full))
    assert code == 0 and "complete; metadata.yaml written (it was missing or did not describe the bag)" in out, (out, err)
    with AnyReader([full]) as reader:
        assert reader.message_count == open_bag(full).message_count
    code, out, _ = cli("bag", "repair", str(full))
    assert code == 0 and "complete; metadata.yaml checked" in out


def _std_msgs_bag(tmp_path):
    from rclpy.serialization import serialize_message
    from std_msgs.msg import String

    from bev_mdo.bag.writer import BagWriter

    bag_dir = tmp_path / "chatter"
    with BagWriter(bag_dir) as writer:
        writer.add_topic("/chatter", "std_msgs/msg/String")
        writer.write("/chatter", serialize_message(String(data="hi")), 1, 1)
    return bag_dir


@pytest.mark.parametrize("kind,problem", [
    ("text", "not an MCAP file"),
    ("random", "not an MCAP file"),
    ("empty", "empty file"),
    ("header", "truncated MCAP header"),
    ("garbage_after_magic", "corrupt MCAP data"),
    ("foreign", "std_msgs/msg/String is not a bev_mdo_msgs type"),
    ("missing", "no such file"),
    ("empty_dir", "holds no .mcap file"),
])
def test_bad_input_is_one_clear_error(kind, problem, tmp_path, full):
    from bev_mdo.bag.errors import BagError
    from bev_mdo.bag.reader import open_bag

    path = tmp_path / f"{kind}.mcap"
    magic = (full / "full_0.mcap").read_bytes()[:8]
    if kind == "text":
        path.write_text("motor_kw: 80\n")
    elif kind == "random":
        path.write_bytes(random.Random(5).randbytes(4096))
    elif kind == "empty":
        path.write_bytes(b"")
    elif kind == "header":
        path.write_bytes((full / "full_0.mcap").read_bytes()[:30])
    elif kind == "garbage_after_magic":
        path.write_bytes(magic + b"\x05" + (2**40).to_bytes(8, "little") + b"x" * 64)
    elif kind == "foreign":
        path = _std_msgs_bag(tmp_path)
    elif kind == "missing":
        path = tmp_path / "nope"
    elif kind == "empty_dir":
        path = tmp_path / "emptydir"
        path.mkdir()
    with pytest.raises(BagError) as info:
        open_bag(path)
    assert problem in str(info.value) and str(path) in str(info.value)
    for argv in (["history", str(path)], ["report", str(path)], ["bag", "info", str(path)]):
        code, _out, err = cli(*argv)
        if kind == "foreign" and argv[0] == "bag":  # `bag info` shows any ros2 bag, and says it is not ours (the docs
            assert code == 0 and "/chatter" in _out  # said exit 2; a malformed-files trial saw 0 and no word)
            assert err.strip().endswith("no bev_mdo_msgs schema: not a bev_mdo recording (history, report, resume "
                                        "and replay refuse it)"), err
            continue
        assert code == 2, (argv, err)
        assert err.count("\n") == 1 and problem in err and str(path) in err


def test_bag_info_reports_truncation(full, tmp_path):
    cut = tmp_path / "cut.mcap"
    data = (full / "full_0.mcap").read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    code, out, err = cli("bag", "info", str(cut))
    assert code == 0 and "truncated" in err and "/bev_mdo/iteration" in out
    shutil.rmtree(full)


@pytest.mark.parametrize("damage,said", [
    (lambda data: data[:-5], "closing magic bytes are cut short (3 of 8)"),
    (lambda data: data[:-1], "closing magic bytes are cut short (7 of 8)"),
    (lambda data: data + b"\x00" * 17, "17 byte(s) after the end of the MCAP data"),
    (lambda data: data[:-8] + b"MCAPMCAP", "closing magic bytes after the footer are invalid"),
], ids=["5_bytes_short", "1_byte_short", "bytes_appended", "bad_end_magic"])
def test_a_damaged_end_is_noted_and_repaired(damage, said, full):
    """A file whose records are all there but whose end is not footer + magic is not complete: rosbags and
    mcap's indexed reader refuse it, so the readers note it and `bag repair` rewrites it."""
    from mcap.reader import make_reader
    from rosbags.highlevel import AnyReader

    from bev_mdo.bag.reader import open_bag

    mcap = full / "full_0.mcap"
    total = open_bag(full).message_count
    mcap.write_bytes(damage(mcap.read_bytes()))
    bag = open_bag(full)
    assert bag.truncated and bag.message_count == total and said in bag.recovery_note()
    for argv in (["history", str(full), "--csv", "-"], ["bag", "info", str(full)],
                 ["report", str(full), "--output-dir", str(full.parent / "rep")]):
        code, _out, err = cli(*argv)
        assert code == 0 and said in err and "bag repair" in err, (argv, err)
    _code, _out, err = cli("resume", str(full), "--transport", "inprocess", "--no-record")
    assert said in err  # noted before anything else (the synthetic config itself cannot be resumed)
    code, out, err = cli("bag", "repair", str(full))
    assert code == 0 and "repaired" in out and (full / "full_0.mcap.bak").is_file(), (out, err)
    assert not open_bag(full).truncated
    with AnyReader([full]) as reader:
        assert reader.message_count == total
    with open(mcap, "rb") as f:
        assert sum(1 for _ in make_reader(f).iter_messages()) == total


def test_damage_in_the_summary_after_the_messages_loses_no_message(full):
    """One flipped byte in the summary section (after DataEnd) made every command refuse the bag, `bag repair`
    included, though every message was intact."""
    from mcap.records import DataEnd
    from mcap.stream_reader import StreamReader
    from rosbags.highlevel import AnyReader

    from bev_mdo.bag.reader import open_bag

    mcap = full / "full_0.mcap"
    whole = open_bag(full)
    reference = _decoded_iterations(whole)
    data = mcap.read_bytes()
    with open(mcap, "rb") as f:
        data_end = next(f.tell() for record in StreamReader(f, skip_magic=False).records if isinstance(record, DataEnd))
    summary_len = len(data) - 8 - data_end
    assert summary_len > 100
    noted = []
    for offset in range(data_end + 9, len(data) - 40, max(1, summary_len // 12)):  # bytes inside summary records
        damaged = bytearray(data)
        damaged[offset] ^= 0xFF
        mcap.write_bytes(bytes(damaged))
        bag = open_bag(full)
        assert _decoded_iterations(bag) == reference, offset  # every message, as recorded
        if bag.truncated:
            assert "in the summary after the messages" in bag.recovery_note()
            noted.append(bytes(damaged))
    assert noted  # some flips break a summary record's parsing: those are the ones that were refused
    mcap.write_bytes(noted[0])
    code, out, err = cli("bag", "repair", str(full))
    assert code == 0 and "repaired" in out, (out, err)
    assert not open_bag(full).truncated
    with AnyReader([full]) as reader:
        assert reader.message_count == whole.message_count


def test_repair_reads_on_past_a_damaged_chunk(full):
    """One flipped byte inside a chunk made every reader and `bag repair` refuse the whole bag, though the
    chunks before and after it were intact. The readers still refuse it (its records cannot be trusted);
    repair keeps every message of the other chunks."""
    from mcap.records import Chunk
    from mcap.stream_reader import StreamReader
    from rosbags.highlevel import AnyReader

    from bev_mdo.bag.reader import open_bag

    mcap = full / "full_0.mcap"
    reference = _decoded_iterations(open_bag(full))
    data = mcap.read_bytes()
    with open(mcap, "rb") as f:
        reader, chunks, start = StreamReader(f, skip_magic=False, emit_chunks=True), [], 8
        for record in reader.records:
            if isinstance(record, Chunk):
                chunks.append((start, f.tell(), record.message_end_time))
            start = f.tell()
    assert len(chunks) >= 4
    begin, end, _ = chunks[len(chunks) // 2]
    damaged = bytearray(data)
    damaged[end - 20] ^= 0xFF  # inside the middle chunk's records
    mcap.write_bytes(bytes(damaged))
    code, _, err = cli("bag", "info", str(full))
    assert code == 2 and f"corrupt MCAP data: the chunk at bytes {begin}-{end} is damaged" in err
    code, out, err = cli("bag", "repair", str(full))
    assert code == 0 and f"1 damaged chunk(s) left out (bytes {begin}-{end})" in out, (out, err)
    kept = _decoded_iterations(open_bag(full))
    assert 0 < len(kept) < len(reference) and kept[-1] == reference[-1]  # the chunks after it too
    assert all(k in reference for k in kept)
    with AnyReader([full]) as rosbags_reader:
        assert rosbags_reader.message_count == len(kept)


@pytest.mark.parametrize("failure", [KeyboardInterrupt, lambda: OSError(28, "No space left on device")],
                         ids=["sigint", "disk_full"])
def test_an_interrupted_or_failed_repair_leaves_no_partial_file(failure, full, monkeypatch):
    """A SIGINT (or a failure) while `bag repair` wrote the new file left `<file>.repairing` beside the bag.
    Now it is removed, and the bag file is the original, untouched; a repair run afterwards works."""
    from bev_mdo.bag import repair as repair_module

    mcap = full / "full_0.mcap"
    data = mcap.read_bytes()
    mcap.write_bytes(data[: int(len(data) * 0.6)])
    truncated = mcap.read_bytes()
    real_writer = repair_module.mcap_writer

    def writer_that_stops(stream, profile):
        writer = real_writer(stream, profile)
        written = []

        def add_message(*args, **kwargs):
            written.append(args)
            if len(written) == 5:  # some messages are in the partial file by now
                raise failure()
            return type(writer).add_message(writer, *args, **kwargs)

        writer.add_message = add_message
        return writer

    monkeypatch.setattr(repair_module, "mcap_writer", writer_that_stops)
    code, out, err = cli("bag", "repair", str(full))
    if failure is KeyboardInterrupt:
        assert code == 130, (out, err)
    else:  # a full disk: one line and exit 2, as a read-only folder (PermissionError); it was exit 7
        assert code == 2 and not out, (out, err)
        assert err.splitlines() == [f"bev-mdo bag: error: {mcap}: the repair could not be written "
                                    "(No space left on device); the bag is unchanged"], err
    assert sorted(p.name for p in full.iterdir()) == ["full_0.mcap", "metadata.yaml"]
    assert mcap.read_bytes() == truncated
    monkeypatch.setattr(repair_module, "mcap_writer", real_writer)
    code, out, err = cli("bag", "repair", str(full))
    assert code == 0 and "repaired" in out and (full / "full_0.mcap.bak").read_bytes() == truncated, (out, err)
    assert not (full / "full_0.mcap.repairing").exists()


def _cut(full):
    mcap = full / "full_0.mcap"
    mcap.write_bytes(mcap.read_bytes()[: int(mcap.stat().st_size * 0.6)])
    return mcap, mcap.read_bytes(), (full / "metadata.yaml").read_bytes()


def test_a_disk_that_fills_while_the_original_is_copied_leaves_no_partial_backup(full, monkeypatch):
    """Where the file system has no hard links the backup is a copy: a full disk during it left a partial
    `<file>.bak` beside the bag (and exit 7). Now the bag, its metadata.yaml and the folder are as before."""
    from bev_mdo.bag import repair as repair_module
    from bev_mdo.bag.reader import open_bag

    mcap, truncated, yaml_before = _cut(full)
    readable = open_bag(full).message_count

    def no_link(src, dst):
        raise OSError(errno.EPERM, "Operation not permitted")

    def copy_that_fills_the_disk(src, dst):
        with open(src, "rb") as a, open(dst, "wb") as b:
            b.write(a.read(100))
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(repair_module.os, "link", no_link)
    monkeypatch.setattr(repair_module.shutil, "copy2", copy_that_fills_the_disk)
    code, out, err = cli("bag", "repair", str(full))
    assert code == 2 and not out, (out, err)
    assert err.splitlines() == [f"bev-mdo bag: error: {mcap}: the repair could not be written "
                                "(No space left on device); the bag is unchanged"], err
    assert sorted(p.name for p in full.iterdir()) == ["full_0.mcap", "metadata.yaml"]
    assert mcap.read_bytes() == truncated and (full / "metadata.yaml").read_bytes() == yaml_before
    assert open_bag(full).message_count == readable


def test_a_metadata_yaml_that_cannot_be_written_is_one_line_and_leaves_no_partial_file(full, monkeypatch):
    """The bag was rewritten, then the disk filled while metadata.yaml was written: one line saying so
    (exit 2), no `metadata.yaml.tmp` left, the repaired bag readable; a repair afterwards finishes it."""
    from pathlib import Path

    from bev_mdo.bag.reader import open_bag

    mcap, truncated, yaml_before = _cut(full)
    real_write_text = Path.write_text

    def write_that_fills_the_disk(self, data, *args, **kwargs):
        if self.name.endswith(".yaml.tmp"):
            real_write_text(self, data[:50], *args, **kwargs)
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_write_text(self, data, *args, **kwargs)

    monkeypatch.setattr(Path, "write_text", write_that_fills_the_disk)
    code, out, err = cli("bag", "repair", str(full))
    assert code == 2 and not out, (out, err)
    assert err.splitlines() == [f"bev-mdo bag: error: {full / 'metadata.yaml'}: the repair could not be written (No "
                                f"space left on device); the bag is repaired (original kept as {mcap}.bak), its "
                                "metadata.yaml is not"], err
    assert sorted(p.name for p in full.iterdir()) == ["full_0.mcap", "full_0.mcap.bak", "metadata.yaml"]
    assert (full / "metadata.yaml").read_bytes() == yaml_before and (full / "full_0.mcap.bak").read_bytes() == truncated
    assert not open_bag(full).truncated
    monkeypatch.setattr(Path, "write_text", real_write_text)
    code, out, err = cli("bag", "repair", str(full))
    assert code == 0 and "metadata.yaml written" in out, (out, err)


def test_a_metadata_yaml_that_is_a_folder_is_named_as_what_could_not_be_written(full, capsys):
    """The line blamed full_0.mcap, which the repair had not touched."""
    (full / "metadata.yaml").unlink()
    (full / "metadata.yaml").mkdir()
    before = (full / "full_0.mcap").read_bytes()
    code, out, err = cli("bag", "repair", str(full))
    assert code == 2 and not out and err.splitlines() == [
        f"bev-mdo bag: error: {full / 'metadata.yaml'}: the repair could not be written (Is a directory); "
        "the bag is unchanged"], err
    assert (full / "full_0.mcap").read_bytes() == before and sorted(p.name for p in full.iterdir()) == [
        "full_0.mcap", "metadata.yaml"]


def test_a_damaged_length_inside_the_header_is_named_and_repaired(full):
    """One flipped byte in the header's profile length (a string's length field, so the record reads past its own
    end): `history` said "the record after byte 0 cannot be read", and `bag repair` "truncated MCAP header", keeping
    nothing, though the mcap library reads every message. The readers name the header and what is wrong with it;
    the repair leaves the header out (it writes its own) and keeps every message."""
    from mcap.reader import make_reader

    from bev_mdo.bag.reader import open_bag

    mcap = full / "full_0.mcap"
    total = open_bag(full).message_count
    data = bytearray(mcap.read_bytes())
    data[20] ^= 0x01  # the high byte of the profile's length (bytes 17-20, after the opcode and record length)
    mcap.write_bytes(bytes(data))
    with open(mcap, "rb") as f:
        assert sum(1 for _ in make_reader(f).iter_messages()) == total
    end = 17 + int.from_bytes(data[9:17], "little")
    for argv in (["history", str(full)], ["bag", "info", str(full)]):
        code, _out, err = cli(*argv)
        assert code == 2 and err.count("\n") == 1, err
        assert (f"corrupt MCAP data: the header at bytes 8-{end} is damaged (a length field inside it points past the "
                "record); run `bev-mdo bag repair` to keep the records after it") in err, err
    code, out, err = cli("bag", "repair", str(full))
    assert code == 0 and (f"repaired, {total} of {total} messages kept; 1 damaged record(s) left out (bytes 8-{end}: "
                          "the header)") in out, (out, err)
    repaired = open_bag(full)
    assert not repaired.truncated and repaired.message_count == total
