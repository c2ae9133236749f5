"""The order check of iteration records, live and offline.

Live, the recorder checked order before any signature: unsigned or forged records numbered one above each
real one, a forged run 1..200 or a burst of scattered forged numbers made it drop the run's own records (a bag
kept 4 of 114). A signed run's recorder now verifies each record first; a forgery never takes a number. Its
memory stays bounded over every run id it is sent. Offline, readers applied the recorder's bound (a bag of
100006 records in reverse order read 4103); they hold every number. Record 0 (a synthetic bag's) arriving
late was dropped as from the past."""
from __future__ import annotations

import pytest

from bev_mdo.bag.history import RecordOrder, Sequence, history
from bev_mdo.bag.writer import BagWriter
from bev_mdo.protocol.signing import Signer, new_key_file, read_key

TOPIC = "/bev_mdo/iteration"
RUN = "0123456789abcdef"
STAMP_S = 1_700_000_000
NOW_NS = (STAMP_S + 1) * 10**9  # within the window of every record's stamp


def _record(sequence: int, run_id: str = RUN, motor_kw: float = 80.0):
    from bev_mdo_msgs.msg import IterationRecord, NamedArray

    rec = IterationRecord(run_id=run_id, sequence=sequence, iteration=sequence, formulation="mdf",
                          optimizer="SLSQP", objective_name="energy_wh_per_km", objective=150.0, feasible=True)
    rec.header.stamp.sec = STAMP_S
    rec.design = NamedArray(names=["motor_kw", "gear_ratio", "battery_kwh"], batch_size=1,
                            values=[motor_kw, 8.0, 24.0])
    return rec


def _plain(sequence: int, run_id: str = RUN) -> bytes:
    from rclpy.serialization import serialize_message

    return serialize_message(_record(sequence, run_id))


@pytest.fixture
def keys(tmp_path):
    """(the run's key file, its Signer, a Signer of another key)."""
    key_file = new_key_file(tmp_path / "keys")
    return key_file, Signer(read_key(key_file)), Signer(read_key(new_key_file(tmp_path / "other")))


def test_forged_records_take_no_number_at_a_signed_runs_recorder(keys):
    """The three floods of the trial, each beside the run's own 114 records: all of them are kept."""
    _, signer, other = keys
    own = [signer.sign_iteration(_record(s, motor_kw=80.0 + s)) for s in range(1, 115)]
    floods = {
        "one above each": lambda: [x for s in range(1, 115) for x in (other.sign_iteration(_record(s + 1)), own[s - 1])],
        "a run 1..200 first": lambda: [*(_plain(s) for s in range(1, 201)), *own],
        "4097 scattered first": lambda: [*(_plain(10**6 + 7 * k) for k in range(4097)), *own],
    }
    for name, stream in floods.items():
        order = RecordOrder(RUN, window_s=30.0, verify=signer.verify_iteration)
        kept = [d for d in stream() if order.keep(d, NOW_NS)]
        assert kept == own, (name, len(kept))
        assert order.order.missing == 0 and order.order.late == 0, name
        assert set(order.dropped) <= {"forged", "unsigned"} and sum(order.dropped.values()) == {
            "one above each": 114, "a run 1..200 first": 200, "4097 scattered first": 4097}[name], order.dropped
    order = RecordOrder(RUN, window_s=30.0, verify=signer.verify_iteration)
    assert [order.keep(d, NOW_NS) for d in (_plain(1), other.sign_iteration(_record(1)), own[0], own[0])] == \
        [False, False, True, False]
    assert order.dropped == {"unsigned": 1, "forged": 1, "duplicate": 1}
    assert order.note() == "; dropped 1 duplicate, 1 forged, 1 unsigned iteration record(s)"


def test_the_recorders_memory_is_bounded_over_every_run_id():
    """An unsigned run (anyone may send its records): 20000 sub-run ids <run>-xN, and scattered numbers over
    several of them. The run ids tracked and the numbers held stay bounded; what is beyond is kept, counted and
    said; the closing line says how many records came after a later one."""
    order = RecordOrder(RUN, window_s=30.0)
    assert all(order.keep(_plain(7, f"{RUN}-x{n}"), NOW_NS) for n in range(20_000))
    seq = order.order
    assert len(seq.last) == len(seq.floor) == len(seq.above) == Sequence.RUNS
    assert seq.untracked == 20_000 - Sequence.RUNS
    assert f"; {20_000 - Sequence.RUNS} iteration record(s) of runs beyond the first {Sequence.RUNS} kept unchecked" \
        in order.note()
    bounded = RecordOrder(RUN, window_s=30.0)
    for k in range(6000):  # scattered over 8 runs: none alone holds HELD numbers
        bounded.keep(_plain(2 + 3 * (k // 8) + (k % 8) * 100_000, f"{RUN}-y{k % 8}"), NOW_NS)
    assert sum(len(s) for s in bounded.order.above.values()) <= Sequence.HELD
    assert bounded.order.size <= Sequence.HELD
    late = RecordOrder(RUN, window_s=30.0)
    assert all(late.keep(_plain(s), NOW_NS) for s in (1, 3, 2))
    assert late.note() == "; 1 iteration record(s) recorded after a later one (kept)"


def test_a_reader_holds_every_number_of_a_bag_in_reverse_order(tmp_path):
    """More records than the recorder's bound, written last first: every one is read, in sequence order."""
    n = Sequence.HELD + 904
    bag = tmp_path / "reversed"
    with BagWriter(bag, metadata={"run_id": RUN}) as w:
        w.add_topic(TOPIC, "bev_mdo_msgs/msg/IterationRecord")
        for k, s in enumerate(range(n, 0, -1)):
            w.write(TOPIC, _plain(s), NOW_NS + k)
    checks: dict = {}
    rows = history(bag, checks=checks)
    assert [r["sequence"] for r in rows] == list(range(1, n + 1))
    assert checks["dropped"] == {} and checks["missing"] == 0 and checks["late"] == n - 1


def test_record_zero_is_a_number_like_any_other():
    order = Sequence()
    assert [order.check("r", s) for s in (1, 2, 0, 0, 3)] == [None, None, None, "from the past", None]
    assert order.late == 1 and order.missing == 0
    never = Sequence()
    assert [never.check("r", s) for s in (1, 2, 3)] == [None] * 3 and never.missing == 0  # 0 is never missing
    first = Sequence()
    assert [first.check("r", s) for s in (0, 0, 2, 1)] == [None, "duplicate", None, None]
    assert first.late == 1 and first.missing == 0


def test_record_zero_recorded_late_is_read_first(tmp_path):
    bag = tmp_path / "zero"
    with BagWriter(bag, metadata={"run_id": RUN}) as w:
        w.add_topic(TOPIC, "bev_mdo_msgs/msg/IterationRecord")
        for k, s in enumerate((1, 0, 2)):
            w.write(TOPIC, _plain(s), NOW_NS + k)
    checks: dict = {}
    assert [r["sequence"] for r in history(bag, checks=checks)] == [0, 1, 2]
    assert checks["dropped"] == {} and checks["late"] == 1 and checks["missing"] == 0


def test_replay_of_a_bag_with_a_gap_says_what_it_left_out(tmp_path, ros_domain):
    """It said "not replayed; 1 iteration record(s) missing" though every record was replayed."""
    from bev_mdo.ros.replay import replay

    bag = tmp_path / "gap"
    with BagWriter(bag, metadata={"run_id": RUN}) as w:
        w.add_topic(TOPIC, "bev_mdo_msgs/msg/IterationRecord")
        for k, s in enumerate((1, 3, 3)):
            w.write(TOPIC, _plain(s), NOW_NS + k)
    said: list[str] = []
    stats = replay(bag, rate=None, log=said.append)
    assert stats.messages == 2
    assert said == [f"{bag / 'gap_0.mcap'}: not replaying 1 duplicate iteration record(s); 1 iteration record(s) "
                    "missing"]



def test_a_recorder_without_the_key_keeps_the_genuine_records_a_forger_numbered_first(keys, rclpy_context, tmp_path):
    """`bev-mdo record` with no config (no key) ordered records it cannot verify: a forger who sent the run's
    numbers first had a genuine record dropped "from the past" (history --key-file read 5 of 6 and said nothing
    of it) and chose the count of "missing" in its closing line (99953). It keeps every fresh record of the run
    and holds no number; history verifies with the key and reads the run's records once and in order."""
    from rclpy.parameter import Parameter

    from bev_mdo.ros.recorder_node import RecorderNode

    key_file, signer, other = keys
    own = [signer.sign_iteration(_record(s, motor_kw=80.0 + s)) for s in range(1, 7)]
    forged = [other.sign_iteration(_record(s)) for s in (2, 5)] + [_plain(100000)]
    bag = tmp_path / "standalone"
    recorder = RecorderNode(context=rclpy_context, node_name="keyless_recorder", parameter_overrides=[
        Parameter("bag_path", value=str(bag)), Parameter("discovery_period_s", value=3600.0)])
    try:
        recorder.writer.add_topic(TOPIC, "bev_mdo_msgs/msg/IterationRecord")
        on_message = recorder._callback(TOPIC, "bev_mdo_msgs/msg/IterationRecord")
        for data in (own[0], *forged, *own[1:], own[3]):  # the genuine record 4 arrives twice
            on_message(data, {"received_timestamp": NOW_NS})
        assert recorder.received == 10 and recorder.order.dropped == {} and recorder.order.order.missing == 0
        assert recorder.order.note() == ("; 10 iteration record(s) kept as received (no key to verify them: the "
                                          "readers verify and order them)")
        stale = [d for d in own[:1] if not recorder.order.keep(d, NOW_NS + 3600 * 10**9)]
        assert stale == own[:1] and recorder.order.dropped == {"expired": 1}  # a record sent again long after
    finally:
        recorder.writer.close()
        recorder.destroy_node()
    checks: dict = {}
    rows = history(bag, RUN, key_file=str(key_file), checks=checks)
    assert [(r["sequence"], r["design"]["motor_kw"]) for r in rows] == [(s, 80.0 + s) for s in range(1, 7)], rows
    assert checks["missing"] == 0 and checks["dropped"] == {"forged": 2, "from the past": 1, "unsigned": 1}, checks


@pytest.mark.parametrize("dropped,said", [
    ({"of another run": 1}, "; not replaying 1 iteration record(s) of another run"),
    ({"duplicate": 2, "from the past": 1}, "; not replaying 2 duplicate, 1 from the past iteration record(s)"),
    ({"of another run": 3, "duplicate": 1},
     "; not replaying 1 duplicate iteration record(s) and 3 iteration record(s) of another run"),
])
def test_what_is_left_out_reads_as_a_sentence(dropped, said):
    """`replay` said "not replaying 1 of another run iteration record(s)"."""
    order = RecordOrder(RUN)
    order.dropped = dict(dropped)
    assert order.note("not replaying") == said


def test_a_recorder_says_no_iteration_record_came_only_when_none_came():
    """The review: a replay whose records were all dropped as expired was told 'no iteration record' with a
    cause that did not apply; dropped records are note()'s to say."""
    order = RecordOrder(RUN)
    assert "no iteration record came" in order.none_note()
    assert order.keep(_plain(1), NOW_NS) and order.none_note() == ""
    expired = RecordOrder(RUN)
    assert not expired.keep(_plain(1), NOW_NS + 10**15) and expired.none_note() == ""
    assert "expired" in expired.note()
