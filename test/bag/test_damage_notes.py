"""What the readers and `bag repair` say about a damaged bag: the chunks kept past a damaged one that held the
channels, plain words instead of an exception's text, damage the mcap library does not check (an attachment, the
summary, a metadata record), and how many messages of how many were kept."""
from __future__ import annotations

import pytest

from .conftest import cli, write_synthetic

TOTAL = 200  # messages of write_synthetic(n_iterations=40): two requests, two results, one record each


@pytest.fixture
def full(tmp_path):
    bag_dir = tmp_path / "full"
    write_synthetic(bag_dir, n_iterations=40, chunk_size_bytes=1500)
    return bag_dir


def _records(mcap):
    """[(start, end, record)] of the file's top-level records (chunks whole), in file order."""
    from mcap.stream_reader import StreamReader

    out, start = [], 8
    with open(mcap, "rb") as f:
        for record in StreamReader(f, skip_magic=False, emit_chunks=True).records:
            out.append((start, f.tell(), record))
            start = f.tell()
    return out


def _damage(mcap, *offsets, mask=0x01):
    data = bytearray(mcap.read_bytes())
    for offset in offsets:
        data[offset] ^= mask
    mcap.write_bytes(bytes(data))


def _rosbags_count(bag_dir):
    from rosbags.highlevel import AnyReader

    with AnyReader([bag_dir]) as reader:
        return reader.message_count, sorted(c.topic for c in reader.connections)


def test_repair_keeps_the_chunks_after_a_damaged_one_that_held_the_channels(full):
    """A flipped byte in the first chunk, which holds every channel record: `bag repair` stopped with 'message on
    unknown channel N' (exit 2), though the summary holds every channel. Now it takes them from there."""
    from mcap.records import Chunk

    from bev_mdo.bag.reader import open_bag

    mcap = full / "full_0.mcap"
    topics = _rosbags_count(full)[1]
    begin, end, _ = next(r for r in _records(mcap) if isinstance(r[2], Chunk))
    _damage(mcap, end - 20)
    code, out, err = cli("bag", "repair", str(full))
    assert code == 0 and f"1 damaged chunk(s) left out (bytes {begin}-{end})" in out, (out, err)
    bag = open_bag(full)
    assert not bag.truncated and 0 < bag.message_count < TOTAL
    assert f"{bag.message_count} of {TOTAL} messages kept" in out
    assert _rosbags_count(full) == (bag.message_count, topics)  # every topic, the later chunks' messages


@pytest.mark.parametrize("where", ["metadata_record", "chunk"])
def test_corrupt_data_is_said_in_plain_words_naming_repair(where, full):
    """Eight bytes flipped in the rosbag2 metadata record (after every message) gave `corrupt MCAP data after byte N
    (UnicodeDecodeError: 'utf-8' codec can't decode ...)`, a chunk's CRC `(CRCValidationError: crc validation failed
    in Chunk, ...)`: one line in plain words that names `bev-mdo bag repair` now."""
    from mcap.records import Chunk, Metadata

    mcap = full / "full_0.mcap"
    kind = Metadata if where == "metadata_record" else Chunk
    begin, end, record = [r for r in _records(mcap) if isinstance(r[2], kind)][-1]
    assert where == "chunk" or record.name == "rosbag2"
    mid = (begin + end) // 2
    _damage(mcap, *range(mid, mid + 8), mask=0xFF)
    said = (f"the metadata record at bytes {begin}-{end} is damaged (it cannot be read)" if where == "metadata_record"
            else f"the chunk at bytes {begin}-{end} is damaged")
    for argv in (["history", str(full)], ["report", str(full), "--output-dir", str(full.parent / "rep")],
                 ["bag", "info", str(full)], ["resume", str(full), "--transport", "inprocess", "--no-record"]):
        code, _out, err = cli(*argv)
        assert code == 2 and err.count("\n") == 1, (argv, err)
        assert said in err and "run `bev-mdo bag repair`" in err and "Error" not in err, (argv, err)
    code, out, err = cli("bag", "repair", str(full))
    kept = TOTAL if where == "metadata_record" else None
    assert code == 0 and "repaired" in out and (kept is None or f"{TOTAL} of {TOTAL} messages kept" in out), (out, err)


def _attachment_data(records, _mcap):
    from mcap.records import Attachment

    begin, end, record = next(r for r in records if isinstance(r[2], Attachment))
    assert record.name == "config.yaml"
    return end - 10  # inside its data (its CRC is the last 4 bytes)


def _summary_channel_topic(records, _mcap):
    from mcap.records import Channel, DataEnd

    data_end = next(i for i, r in enumerate(records) if isinstance(r[2], DataEnd))
    begin, _end, record = next(r for r in records[data_end:] if isinstance(r[2], Channel))
    assert record.topic.startswith("/bev_mdo/")
    return begin + 1 + 8 + 2 + 2 + 4 + 3  # opcode, length, id, schema id, topic length: a letter of its topic


def _rosbag2_record_count(records, mcap):
    from mcap.records import Metadata

    begin, end, _record = next(r for r in records if isinstance(r[2], Metadata) and r[2].name == "rosbag2")
    at = mcap.read_bytes().find(f"message_count: {TOTAL}".encode(), begin, end)
    assert at > 0
    return at + len("message_count: ")  # its count, 200 -> 300: still valid text


@pytest.mark.parametrize("where,said", [
    (_attachment_data, "attachment config.yaml damaged (its CRC check fails; left out)"),
    (_summary_channel_topic, "damaged in the summary after the messages (its CRC check fails)"),
    (_rosbag2_record_count, "a metadata record between the chunks is damaged (the data section's CRC check fails)"),
], ids=["attachment", "summary_channel", "rosbag2_record"])
def test_damage_the_library_does_not_check_is_noted_and_repaired(where, said, full):
    """One flipped bit in the config.yaml attachment, in a summary Channel record or in the rosbag2 metadata record
    went unnoticed: every command exited 0 without a word, and `bag repair` said 'complete; metadata.yaml checked'.
    The attachment and summary CRCs are checked now, and bags are written with the data section's CRC."""
    from bev_mdo.bag.reader import open_bag, read_config

    mcap = full / "full_0.mcap"
    config = read_config(open_bag(full))
    _damage(mcap, where(_records(mcap), mcap))
    bag = open_bag(full)
    assert bag.truncated and bag.message_count == TOTAL and said in bag.recovery_note()
    for argv in (["bag", "info", str(full)], ["history", str(full), "--csv", "-"]):
        code, _out, err = cli(*argv)
        assert code == 0 and said in err and f"read {TOTAL} of {TOTAL} messages" in err, (argv, err)
    code, out, err = cli("bag", "repair", str(full))
    assert code == 0 and f"repaired, {TOTAL} of {TOTAL} messages kept; {said}" in out, (out, err)
    repaired = open_bag(full)
    assert not repaired.truncated and read_config(repaired) == config  # (from the bev_mdo record)
    assert "config.yaml" not in repaired.attachments or where is not _attachment_data
    assert _rosbags_count(full)[0] == TOTAL


def test_notes_say_how_many_messages_of_how_many_were_kept(full):
    """`history` of a bag cut in half said 'read 206 messages' though its metadata.yaml says 232, and `bag repair`
    of one with a damaged last chunk '206 messages kept': where metadata.yaml or the summary gives the number
    written, both say 'N of M'."""
    from mcap.records import Chunk

    mcap = full / "full_0.mcap"
    data = mcap.read_bytes()
    mcap.write_bytes(data[: len(data) // 2])
    code, _out, err = cli("history", str(full), "--csv", "-")
    assert code == 0 and f" of {TOTAL} messages from the first" in err, err
    mcap.write_bytes(data)  # whole again: now its last chunk damaged (the summary says how many were written)
    begin, end, _ = [r for r in _records(mcap) if isinstance(r[2], Chunk)][-1]
    _damage(mcap, end - 20)
    (full / "metadata.yaml").unlink()
    code, out, err = cli("bag", "repair", str(full))
    assert code == 0 and f" of {TOTAL} messages kept; 1 damaged chunk(s) left out (bytes {begin}-{end})" in out, err
