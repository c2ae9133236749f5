"""The baseline is analysed before the optimisation by its own evaluator: what
that evaluator dropped and refused is the run's too (sessions.merge_baseline_stats)."""
from __future__ import annotations

from bev_mdo.sessions import merge_baseline_stats


def test_refusals_seen_only_by_the_baseline_are_the_runs():
    stats = {"dropped": {"unsigned": 3}, "refused_instances": {}}
    seen = {"dropped": {"refused_instance": 1, "info_unsigned": 1, "unsigned": 2},
            "refused": {"energy energy_node_foreign": "fingerprint 1 != 2: vehicle.drag_area_m2: 0.9"}}
    merge_baseline_stats(stats, seen)
    assert stats["refused_instances"] == seen["refused"]
    assert stats["dropped"] == {"refused_instance": 1, "info_unsigned": 1, "unsigned": 5}


def test_a_declaration_judged_by_both_is_counted_once():
    refused = {"energy energy_node_attacker0": "unsigned declaration", "energy energy_node_attacker1": "forged"}
    stats = {"dropped": {"refused_instance": 2, "info_unsigned": 1, "info_forged": 1}, "refused_instances": refused}
    merge_baseline_stats(stats, {"dropped": {"refused_instance": 2, "info_unsigned": 1, "info_forged": 1},
                                  "refused": dict(refused)})
    assert stats["dropped"] == {"refused_instance": 2, "info_unsigned": 1, "info_forged": 1}
    assert stats["refused_instances"] == refused


def test_without_a_baseline_nothing_changes():
    stats = {"dropped": {"stale": 1}, "refused_instances": {}}
    merge_baseline_stats(stats, {})
    assert stats == {"dropped": {"stale": 1}, "refused_instances": {}}
