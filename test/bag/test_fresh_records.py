"""Every record is fresh and read in its run's order, and a bag's signing state is its own: a captured record
replayed, a record of another run, and a bag whose stored sign_key_file was blanked are each
dropped and counted, or refused, by history, report and resume."""
from __future__ import annotations

import yaml
import numpy as np
import pytest

from bev_mdo.bag.errors import BagError
from bev_mdo.bag.history import history
from bev_mdo.bag.reader import open_bag
from bev_mdo.bag.writer import BagWriter
from bev_mdo.cli import main
from bev_mdo.protocol.signing import Signer, new_key_file, read_key
from bev_mdo.testing import REPO

TOPIC = "/bev_mdo/iteration"
RUN = "0123456789abcdef"


def _record(run_id: str, sequence: int, motor_kw: float):
    from bev_mdo_msgs.msg import IterationRecord, NamedArray

    rec = IterationRecord(run_id=run_id, sequence=sequence, iteration=sequence - 1, formulation="mdf",
                          optimizer="SLSQP", objective_name="energy_wh_per_km", objective=150.0 - sequence,
                          feasible=True)
    rec.header.stamp.sec = 1_700_000_000 + sequence
    rec.design = NamedArray(names=["motor_kw", "gear_ratio", "battery_kwh"], batch_size=1,
                            values=[motor_kw, 8.0, 24.0])
    return rec


def _config(key_file: str) -> str:
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["ros"] = {"sign_key_file": key_file}
    return yaml.safe_dump(raw, sort_keys=False)


def _bag(path, records: list[bytes], config_yaml: str, run_id: str = RUN):
    with BagWriter(path, metadata={"config_yaml": config_yaml, "run_id": run_id}) as w:
        w.add_topic(TOPIC, "bev_mdo_msgs/msg/IterationRecord")
        for t, data in enumerate(records):
            w.write(TOPIC, data, 1_700_000_000_000_000_000 + t)
    return path


@pytest.fixture
def signed(tmp_path):
    """(key file, signer, the signed bytes of a run's records 1..4: motor_kw 80, 81, 82, 83)."""
    key_file = new_key_file(tmp_path / "keys")
    signer = Signer(read_key(key_file))
    return key_file, signer, [signer.sign_iteration(_record(RUN, s, 79.0 + s)) for s in range(1, 5)]


def _rewrite_config(src, dst, config_yaml: str) -> None:
    """A copy of bag `src` at `dst` whose stored config (metadata and attachment) is `config_yaml`:
    everything else, the signing record and the signed records included, as recorded."""
    from mcap.writer import Writer

    bag = open_bag(src)
    dst.mkdir(parents=True)
    with open(dst / f"{dst.name}_0.mcap", "wb") as f:
        w = Writer(f)
        w.start(profile="ros2", library="test")
        for name, data in bag.metadata.items():
            w.add_metadata(name, {**data, "config_yaml": config_yaml} if name == "bev_mdo" else data)
        w.add_attachment(0, 0, "config.yaml", "application/yaml", config_yaml.encode())
        schemas = {sid: w.register_schema(s.name, s.encoding, s.data) for sid, s in bag.schemas.items()}
        channels = {cid: w.register_channel(c.topic, c.message_encoding, schemas[c.schema_id], dict(c.metadata))
                    for cid, c in bag.channels.items()}
        for m in bag.messages():
            w.add_message(channels[m.channel_id], m.log_time_ns, m.data, m.publish_time_ns, m.sequence)
        w.finish()


def _cli(capsys, *argv) -> tuple[int, str, str]:
    status = main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


def test_a_replayed_record_is_dropped_and_counted_by_history_report_and_resume(tmp_path, signed, capsys):
    key_file, _, recs = signed
    # the run's records, then record 1 captured and sent again, then record 3 again (a duplicate of
    # nothing newer: from the past), then the genuine last one arrives twice
    bag = _bag(tmp_path / "replayed", [*recs[:3], recs[0], recs[1], recs[3], recs[3]], _config(key_file))
    checks: dict = {}
    rows = history(bag, checks=checks)
    assert [r["sequence"] for r in rows] == [1, 2, 3, 4]
    assert checks["dropped"] == {"from the past": 2, "duplicate": 1} and checks["missing"] == 0

    status, out, err = _cli(capsys, "history", str(bag), "--csv", "-")
    assert status == 0 and len(out.strip().splitlines()) == 1 + 4
    assert "dropped 1 duplicate, 2 from the past iteration record(s)" in err

    status, out, err = _cli(capsys, "report", str(bag), "--output-dir", str(tmp_path / "rep"))
    assert status == 0 and "dropped 1 duplicate, 2 from the past" in err
    assert "4 records (iterations 0-3)" in (tmp_path / "rep" / "report.md").read_text()

    from bev_mdo.cli.resume import resume_point

    checks = {}
    _, design, iteration = resume_point(str(bag), checks=checks)
    assert design["motor_kw"] == 83.0 and iteration == 3  # the genuine last record, not the replayed first
    assert checks["dropped"] == {"from the past": 2, "duplicate": 1}


def test_an_old_bag_replayed_before_the_runs_own_records_does_not_displace_them(tmp_path, signed, capsys):
    """A run id used again (by hand) while an old bag of it is replayed: the old records reached the recorder
    first, so the run's own records 1.. were taken for duplicates and records from the past, and history and
    resume read the old run. A record received further than ros.sign_window_s from its stamp is expired."""
    key_file, signer, old = signed  # stamped 1_700_000_001.. s
    own = []
    for s in range(1, 4):  # the run of today: stamped 200 s later, the same run id and key
        rec = _record(RUN, s, 90.0 + s)
        rec.header.stamp.sec += 200
        own.append((rec.header.stamp.sec * 10**9, signer.sign_iteration(rec)))
    bag = tmp_path / "reused"
    with BagWriter(bag, metadata={"config_yaml": _config(key_file), "run_id": RUN}) as w:
        w.add_topic(TOPIC, "bev_mdo_msgs/msg/IterationRecord")
        for k, data in enumerate(old):  # replayed just before the run's own records: received now
            w.write(TOPIC, data, own[0][0] - 10**9 + k)
        for t, data in own:
            w.write(TOPIC, data, t + 10**6)
    checks: dict = {}
    rows = history(bag, checks=checks)
    assert [r["design"]["motor_kw"] for r in rows] == [91.0, 92.0, 93.0]
    assert checks["dropped"] == {"expired": 4} and checks["missing"] == 0
    status, _, err = _cli(capsys, "history", str(bag), "--csv", "-")
    assert status == 0 and "dropped 4 expired iteration record(s)" in err

    from bev_mdo.bag.history import RecordOrder
    from bev_mdo.cli.resume import resume_point

    _, design, iteration = resume_point(str(bag))
    assert design["motor_kw"] == 93.0 and iteration == 2
    order = RecordOrder(RUN, window_s=30.0)  # the recorder's check as they arrive, at the time they arrive
    assert [order.keep(d, own[0][0]) for d in old] == [False] * 4
    assert [order.keep(d, t) for t, d in own] == [True] * 3 and order.dropped == {"expired": 4}


def test_a_record_of_another_run_and_a_gap_are_counted_by_history_report_and_resume(tmp_path, signed, capsys):
    key_file, signer, recs = signed
    other = signer.sign_iteration(_record("fedcba9876543210", 9, 120.0))  # same key, another run, the latest
    bag = _bag(tmp_path / "mixed", [recs[0], other, recs[2], recs[3]], _config(key_file))
    checks: dict = {}
    rows = history(bag, checks=checks)
    assert [r["sequence"] for r in rows] == [1, 3, 4]
    assert checks["other_runs"] == 1 and checks["missing"] == 1 and checks["dropped"] == {}
    said = "1 iteration record(s) missing (gaps in the run's sequence numbers); skipped 1 record(s) of other runs"

    status, out, err = _cli(capsys, "history", str(bag), "--csv", "-")
    assert status == 0 and len(out.strip().splitlines()) == 1 + 3 and said in err
    status, out, err = _cli(capsys, "report", str(bag), "--output-dir", str(tmp_path / "rep"))
    assert status == 0 and said in err
    assert "3 records (iterations 0-3)" in (tmp_path / "rep" / "report.md").read_text()

    from bev_mdo.cli.resume import resume_point

    checks = {}
    _, design, iteration = resume_point(str(bag), checks=checks)
    assert design["motor_kw"] == 83.0 and iteration == 3  # this run's last record, not the other run's
    assert checks["other_runs"] == 1 and checks["missing"] == 1


def test_a_bag_whose_stored_key_file_was_blanked_is_refused(tmp_path, signed, capsys):
    key_file, _, recs = signed
    original = _bag(tmp_path / "original", recs, _config(key_file))
    assert open_bag(original).metadata["bev_mdo_signing"]["signed"] == "true"
    blanked = tmp_path / "blanked"
    _rewrite_config(original, blanked, _config(""))
    with pytest.raises(BagError, match="signed .* names no ros.sign_key_file"):
        history(blanked)
    for argv in (["history", str(blanked)], ["report", str(blanked), "--output-dir", str(tmp_path / "r")],
                 ["resume", str(blanked), "--transport", "inprocess", "--no-record"]):
        status, out, err = _cli(capsys, *argv)
        assert status == 2 and len(err.strip().splitlines()) == 1, (argv, err)
        assert "names no ros.sign_key_file" in err and "--no-verify" in err
    # the right key does not make an edited config acceptable
    with pytest.raises(BagError, match="stored config is not the one recorded"):
        history(blanked, key_file=key_file)
    # turning verification off is explicit, and said
    status, out, err = _cli(capsys, "history", str(blanked), "--no-verify", "--csv", "-")
    assert status == 0 and len(out.strip().splitlines()) == 5 and "verification OFF" in err


def test_a_bag_said_unsigned_whose_records_are_signed_is_refused(tmp_path, signed):
    """Blanking the key and rewriting the signing record to 'not signed' does not turn verification off."""
    key_file, _, recs = signed
    bag = _bag(tmp_path / "stripped", recs, _config(""))  # no key named: the writer records "not signed"
    assert open_bag(bag).metadata["bev_mdo_signing"]["signed"] == "false"
    with pytest.raises(BagError, match=r"records are signed but the bag names no key.*\(was its config edited\?\)"):
        history(bag)


def test_a_bag_with_no_config_whose_records_are_signed_says_so(tmp_path, signed):
    """A recorder started without the run's config (bev-mdo record) keeps signed records it cannot verify: the
    refusal asked "(was its config edited?)" of a bag that never had one."""
    _, _, recs = signed
    bag = _bag(tmp_path / "keyless", recs, "")
    with pytest.raises(BagError, match=r"names no key .*\(it holds no config \(a recorder started without one\)\)"):
        history(bag)


def test_another_key_is_refused_by_fingerprint(tmp_path, signed):
    key_file, _, recs = signed
    bag = _bag(tmp_path / "b", recs, _config(key_file))
    other = new_key_file(tmp_path / "other")
    with pytest.raises(BagError, match="is not the key this run was signed with"):
        history(bag, key_file=other)


def test_an_unsigned_run_says_its_records_are_unverified(tmp_path):
    from rclpy.serialization import serialize_message

    bag = _bag(tmp_path / "plain", [serialize_message(_record(RUN, s, 80.0)) for s in (1, 2)], _config(""))
    checks: dict = {}
    assert len(history(bag, checks=checks)) == 2
    assert "not signed" in checks["unverified"]


def test_replay_leaves_out_the_replayed_and_foreign_records(tmp_path, signed, rclpy_context):
    from rclpy.node import Node

    from bev_mdo.ros.replay import Replayer

    key_file, signer, recs = signed
    other = signer.sign_iteration(_record("fedcba9876543210", 2, 120.0))
    bag = _bag(tmp_path / "replayed", [*recs[:3], recs[0], other, recs[3], recs[3]], _config(key_file))
    node = Node("fresh_records_replay", context=rclpy_context)
    try:
        player = Replayer(node, open_bag(bag), None)
        assert [m.data for m in player.messages] == recs
        assert player.order.dropped == {"duplicate": 1, "from the past": 1, "of another run": 1}
    finally:
        node.destroy_node()


def test_the_recorders_check_keeps_its_own_run_once_and_in_order(signed):
    """RecordOrder is what the recorder node applies to every IterationRecord it receives."""
    from bev_mdo.bag.history import RecordOrder

    _, signer, recs = signed
    other = signer.sign_iteration(_record("fedcba9876543210", 5, 120.0))
    order = RecordOrder(RUN)
    now = (1_700_000_000 + 3) * 10**9  # within the window of every record's stamp
    kept = [r for r in [recs[0], recs[2], recs[0], other, recs[2], recs[3], b"\x00\x01\x00\x00junk"]
            if order.keep(r, now)]
    assert kept == [recs[0], recs[2], recs[3]]
    assert order.dropped == {"from the past": 1, "duplicate": 1, "of another run": 1, "malformed": 1}
    assert order.order.missing == 1
    assert "1 iteration record(s) missing" in order.note()


def test_two_records_recorded_in_each_others_place_are_all_read_in_order(tmp_path, signed, capsys):
    """Record 3 written before record 2 (their bytes, signatures and numbers as sent): history read record 2 as
    one 'from the past', dropped it and counted one missing. Every number is there: all are read, in sequence
    order, and one line says one was recorded after a later one; a record seen before is still dropped."""
    key_file, _, recs = signed
    bag = _bag(tmp_path / "swapped", [recs[0], recs[2], recs[1], recs[3], recs[1]], _config(key_file))
    checks: dict = {}
    rows = history(bag, checks=checks)
    assert [r["sequence"] for r in rows] == [1, 2, 3, 4]
    assert [r["design"]["motor_kw"] for r in rows] == [80.0, 81.0, 82.0, 83.0]
    assert checks["missing"] == 0 and checks["dropped"] == {"from the past": 1} and checks["late"] == 1
    status, out, err = _cli(capsys, "history", str(bag), "--csv", "-")
    assert status == 0 and len(out.strip().splitlines()) == 1 + 4
    assert "1 iteration record(s) recorded after a later one (read in sequence order)" in err
    assert "missing" not in err

    from bev_mdo.bag.history import RecordOrder

    order = RecordOrder(RUN)  # the recorder keeps such a record too (history puts it back in its place)
    assert [order.keep(r, (1_700_000_000 + 3) * 10**9) for r in (recs[0], recs[2], recs[1])] == [True] * 3
    assert order.order.missing == 0 and order.note() == "; 1 iteration record(s) recorded after a later one (kept)"


def test_the_order_check_holds_a_bounded_set_under_a_flood_of_scattered_numbers():
    """The live recorder's check (of an unsigned run: a signed run's forged records are dropped before it):
    a flood of scattered sequence numbers for its run must not grow the numbers it holds without bound (a set
    of every number seen did). What is given up is still counted missing, and a number under the raised floor
    is dropped as from the past."""
    from bev_mdo.bag.history import Sequence

    order, rng = Sequence(held=Sequence.HELD, runs=Sequence.RUNS), np.random.default_rng(1)
    numbers = rng.permutation(np.arange(1, 200_001))[:40_000]
    kept = sum(order.check("run", int(n)) is None for n in numbers)
    assert len(order.above["run"]) <= Sequence.HELD
    assert order.missing == int(numbers.max()) - kept  # every number up to the last that is not kept
    in_order = Sequence()
    assert all(in_order.check("r", n) is None for n in (1, 2, 4, 3, 5)) and in_order.missing == 0
    assert in_order.above["r"] == set() and in_order.late == 1
