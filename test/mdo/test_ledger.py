"""The request ledger (mdo/ledger.py), transport-independent: ids, outstanding and answered requests,
reassigned shares, and why an answer is dropped. Milliseconds, no ROS."""
from __future__ import annotations

from dataclasses import dataclass

from bev_mdo.mdo.ledger import Ledger


@dataclass
class Entry:
    binding: str


def _ledger() -> Ledger[Entry]:
    return Ledger(lambda e: e.binding)


def test_ids_are_unique_and_probes_are_remembered():
    led = _ledger()
    ids = [led.new_id(), led.new_id(probe=True), led.new_id()]
    assert ids == [1, 2, 3] and led.next_id == 4 and led.probes == {2}


def test_an_answer_is_matched_once_then_is_a_duplicate():
    led = _ledger()
    eid = led.new_id()
    e = led.open(eid, "energy", Entry("energy=fp1"))
    assert led.match(eid, "energy", "energy=fp1") is e
    assert led.settle(eid, "energy") is e and not led.pending
    assert led.match(eid, "energy", "energy=fp1") is None
    assert dict(led.dropped) == {"duplicate": 1}


def test_each_kind_of_unwanted_answer_is_named():
    led = _ledger()
    flow = led.new_id()  # a data-flow MDA: one id, an entry per discipline
    for d in ("vehicle_mass", "energy"):
        led.open(flow, d, Entry("tag"))
    probe = led.new_id(probe=True)
    assert led.match(flow, "energy", "other-tag") is None                 # another configuration's answer
    assert led.match(flow, "range", "tag") is None                        # outstanding id, other discipline
    assert led.match(99, "energy", "tag") is None                         # nothing of the kind: stale
    assert led.match(probe, "energy", "tag") is None and led.probe_late == 1  # a late probe answer: not a drop
    assert dict(led.dropped) == {"fingerprint": 1, "mismatched": 1, "stale": 1}
    assert set(led.pending) == {(flow, "vehicle_mass"), (flow, "energy")}  # nothing matched was consumed


def test_a_reassigned_share_and_a_given_up_request_drop_their_late_answers():
    led = _ledger()
    a, b = led.new_id(), led.new_id()
    led.open(a, "energy", Entry(""))
    led.open(b, "energy", Entry(""))
    led.reassign((a, "energy"))   # its instance stalled: re-sent under a new id
    led.close((b, "energy"))      # retries exhausted: its points failed
    assert not led.pending
    assert led.match(a, "energy", "") is None and led.match(b, "energy", "") is None
    assert dict(led.dropped) == {"late_share": 1, "duplicate": 1}


def test_the_transport_counts_its_own_drops_in_the_same_counter():
    led = _ledger()
    led.drop("other_run")
    led.drop("forged")
    assert dict(led.dropped) == {"other_run": 1, "forged": 1}
