"""The timing decisions of a distributed evaluation (mdo/retry.py), without a transport: which
requests are overdue, what is re-sent and to whom, what is given up, which disciplines are hung,
and how row shares are joined. Milliseconds, no ROS."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from bev_mdo.mdo import flow, retry
from bev_mdo.mdo.discipline import EvalResult, PointError
from bev_mdo.mdo.ledger import Ledger

S = 1_000_000_000  # ns per s
POLICY = retry.Policy(timeout_s=2.0, retries=2)


def _sent(index, discipline, n=3, sent_s=0.0, **kw):
    return retry.Sent(index, discipline, SimpleNamespace(name=f"req-{discipline}"), n, int(sent_s * S), **kw)


def test_the_policy_says_what_is_late_when_the_next_is_due_and_when_tries_are_spent():
    a, b = _sent(0, "mass", sent_s=1.0), _sent(1, "energy", sent_s=1.5)
    assert not POLICY.late(a, int(2.999 * S)) and POLICY.late(a, 3 * S)
    assert POLICY.due_s([a, b]) == pytest.approx(3.0)
    assert not POLICY.exhausted(1) and POLICY.exhausted(2)
    assert POLICY.no_answer("energy") == "energy: no answer after 3 attempts of 2 s"


def test_a_timed_out_wave_resends_each_request_once_naming_what_it_waits_for():
    led = Ledger()
    mass = led.open(1, "mass", _sent(0, "mass"))
    shared = SimpleNamespace(name="mda")  # a data-flow MDA: one request for its disciplines
    e1 = led.open(2, "energy", retry.Sent(0, "energy", shared, 3, 0, flow=True))
    e2 = led.open(2, "cost", retry.Sent(1, "cost", shared, 3, 0, flow=True))
    rounds = retry.resend_round(led.pending, attempt=1)
    assert [(p.discipline, late) for p, late in rounds] == [("mass", ["mass"]), ("energy", ["energy", "cost"])]
    assert mass.tries == e1.tries == e2.tries == 1


def test_a_data_flow_discipline_is_hung_only_when_its_sources_answered():
    # energy reads mass; both unanswered: only mass is hung (energy never had its inputs)
    unanswered = {(7, "mass"): _sent(0, "mass", flow=True), (7, "energy"): _sent(1, "energy", flow=True),
                  (8, "cost"): _sent(0, "cost")}
    sources = {"mass": set(), "energy": {"mass"}, "cost": {"mass"}}
    assert retry.hung(unanswered, lambda p: sources[p.discipline]) == ["mass", "cost"]
    # mass answered: energy is to blame
    del unanswered[(7, "mass")]
    assert retry.hung(unanswered, lambda p: sources[p.discipline]) == ["energy", "cost"]


def test_pool_shares_are_resplit_resent_or_given_up():
    pending = {
        (1, "mass"): _sent(0, "mass", target="a", start=0),            # late share: re-split
        (2, "mass"): _sent(0, "mass", target="b", start=3, sent_s=9),  # on time, but its instance left
        (3, "mass"): _sent(0, "mass", target="c", start=6, sent_s=9),  # on time: left alone
        (4, "cost"): _sent(1, "cost"),                                  # whole batch, late: re-sent as is
        (5, "energy"): _sent(2, "energy", target="a", start=0, tries=2),  # late, tries spent
    }
    steps = retry.share_steps(POLICY, pending, 10 * S, gone={("mass", "b")})
    got = {s.key: (s.action, s.why, s.blame) for s in steps}
    assert got == {(1, "mass"): ("reshare", "no answer after 2 s", True),
                   (2, "mass"): ("reshare", retry.LEFT, True),
                   (4, "cost"): ("resend", "no answer after 2 s", False),
                   (5, "energy"): ("give_up", "no answer after 2 s", True)}


def test_a_late_data_flow_share_blames_the_instance_that_had_its_inputs():
    plan = {"mass": {}, "energy": {"m_kg": "mass"}, "cost": {"m_kg": "mass"}}
    # share 4: mass answered, energy and cost did not -> both to blame; share 5: mass (the root)
    # did not answer -> only mass is to blame (its consumers never had inputs)
    pending = {(4, "energy"): _sent(1, "energy", target="e1"), (4, "cost"): _sent(2, "cost"),
               (5, "mass"): _sent(0, "mass", target="m2"), (5, "energy"): _sent(1, "energy", target="e2"),
               (6, "mass"): _sent(0, "mass", target="m1", sent_s=9)}
    tries = {4: 0, 5: 2, 6: 0}
    steps = {s.eid: s for s in retry.flow_share_steps(POLICY, pending, 10 * S, set(), plan, tries.get)}
    assert set(steps) == {4, 5}  # share 6 is on time
    assert steps[4].blame == {("energy", "e1", 3)} and not steps[4].give_up  # cost has no target
    assert steps[5].blame == {("mass", "m2", 3)} and steps[5].give_up
    # an instance that left is to blame whatever its sources, and so named
    steps = retry.flow_share_steps(POLICY, pending, 1 * S, {("energy", "e2")}, plan, tries.get)
    # (the root's instance of that share has not answered either: it is blamed with it)
    assert [(s.eid, s.blame, s.why) for s in steps] == [(5, {("mass", "m2", 3), ("energy", "e2", 3)}, retry.LEFT)]


def test_a_resent_share_goes_to_the_live_instances_in_turn():
    live = ["a", "b", "c"]
    assert [retry.pick(live, eid, 0) for eid in (3, 4, 5)] == ["a", "b", "c"]
    assert retry.pick(live, 3, 1) == "b"


def _res(values, ok=None, errors=None, t=0.5):
    values = np.asarray(values, dtype=float)
    ok = np.ones(values.size, bool) if ok is None else np.asarray(ok)
    return EvalResult({"y": values}, ok, "", t, point_errors=errors or {})


def test_shares_are_joined_in_row_order_with_their_errors_renumbered():
    shares = retry.Shares()
    shares.sent(11, 3, 5, 0)
    shares.sent(10, 0, 3, 1)
    shares.add(11, 0, 3, _res([4, 5], ok=[True, False], errors={1: PointError("y < 0", {})}))
    shares.add(10, 0, 0, _res([1, 2, 3]))
    assert shares.tries(10) == 1 and shares.indices() == {0}
    joined = shares.join(0)
    np.testing.assert_array_equal(joined.outputs["y"], [1, 2, 3, 4, 5])
    np.testing.assert_array_equal(joined.ok, [True, True, True, True, False])
    assert set(joined.point_errors) == {4} and "at point 4" in joined.error
    assert joined.compute_time_s == pytest.approx(1.0)
    # a re-sent share is forgotten whole: the indices that had answered are returned
    assert shares.drop(11) == [0] and 11 not in shares.meta
    np.testing.assert_array_equal(shares.join(0).outputs["y"], [1, 2, 3])


def test_partials_are_joined_only_when_every_share_has_them():
    a, b = _res([1.0]), _res([2.0])
    a.extra["partials"] = {"y/x": np.array([[1.0]])}
    assert "partials" not in retry.join_rows([(0, a), (1, b)]).extra
    b.extra["partials"] = {"y/x": np.array([[2.0]])}
    np.testing.assert_array_equal(retry.join_rows([(1, b), (0, a)]).extra["partials"]["y/x"], [[1.0], [2.0]])


def test_rows_per_discipline_counts_the_rows_each_sources_evaluated():
    plan = {"mass": {}, "energy": {"m_kg": "mass"}}
    out = {"mass": EvalResult({"m_kg": np.array([1.0, np.nan, 3.0])}, np.array([True, False, True]), ""),
           "energy": _res([1, 2, 3])}
    assert flow.rows_per_discipline(plan, out, 3, ["mass", "energy"]) == {"mass": 3, "energy": 2}
    assert flow.rows_per_discipline(plan, out, 3, ["energy"]) == {"energy": 2}
