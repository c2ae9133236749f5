"""Every JSON file bev_mdo writes is strict JSON (RFC 8259): a non-finite number is null, never a
bare NaN or Infinity (which Python's json writes and jq, JavaScript and most parsers refuse)."""
from __future__ import annotations

import json
import types

import pytest

NAN, INF = float("nan"), float("inf")
# what mdo.active.analyse returns for an end point whose constraint output failed (NaN)
FAILED_ANSWERS = {"feasible": False, "violated": [{"name": "g", "value": NAN, "margin": NAN, "violation": INF}],
                  "lines": ["no value: g <= 0 (the point failed)"]}


def _strict(text: str):
    def refuse(word):
        raise AssertionError(f"{word} in a JSON file")
    return json.loads(text, parse_constant=refuse)


def test_front_and_summary_json_are_strict(tmp_path):
    """api.pareto.finish (front.json, the topology study's summary.json) used json.dumps(default=float)."""
    from bev_mdo.api import pareto

    pareto.finish(tmp_path / "summary.json", {"benchmark": {"DM-DA": {"accel_time_0_100_s": INF}},
                                              "front": [{"x": NAN}], "out": "skipped"},
                  types.SimpleNamespace(stats={}), skip=("out",))
    doc = _strict((tmp_path / "summary.json").read_text())
    assert doc == {"benchmark": {"DM-DA": {"accel_time_0_100_s": None}}, "front": [{"x": None}]}


def test_answers_json_beside_a_ros_bag_is_strict(tmp_path, monkeypatch):
    """api.runbag.finish wrote answers.json with json.dumps(default=float): NaN, Infinity."""
    from bev_mdo.api import runbag
    from bev_mdo.bag.history import ANSWERS_FILE

    monkeypatch.setattr(runbag, "answers", lambda config, result: FAILED_ANSWERS)
    runbag.finish({}, {}, {"bag": str(tmp_path / "bag")})
    doc = _strict((tmp_path / "bag" / ANSWERS_FILE).read_text())
    assert doc["violated"][0] == {"name": "g", "value": None, "margin": None, "violation": None}


def test_answers_record_of_an_in_process_bag_is_strict(tmp_path):
    """The bag's bev_mdo_answers metadata record (what `bev-mdo report` reads) had the same NaN."""
    pytest.importorskip("rclpy")
    from bev_mdo.api.runbag import InProcessBag
    from bev_mdo.bag.reader import open_bag
    from bev_mdo.bag.history import ANSWERS_METADATA

    bag = InProcessBag(tmp_path / "bag", {"name": "t"}, "run1")
    bag.close(FAILED_ANSWERS)
    rec = open_bag(tmp_path / "bag").metadata[ANSWERS_METADATA]
    assert _strict(rec["answers_json"])["violated"][0]["violation"] is None
