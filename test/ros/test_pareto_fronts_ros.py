"""``bev-mdo pareto --transport ros`` on the constrained test problems of examples/pareto/ (SRN, TNK):
one discipline node each, the recorder writing the bag; the front matches the analytic one (the
tolerances of test/mdo/pareto_fronts.py) and equals the in-process front of the same seed."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from bev_mdo.testing import PYTHON, ros_env

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "mdo"))
from pareto_fronts import EXAMPLES, POP, RUNS, check_front  # noqa: E402

ROS_DOMAIN = 93
PROBLEMS = ("srn", "tnk")


@pytest.fixture(scope="module")
def runs(tmp_path_factory, ros_domain):
    d = tmp_path_factory.mktemp("pareto_fronts_ros")
    env = ros_env(ros_domain)
    out = {}
    for problem in PROBLEMS:
        for transport in ("ros", "inprocess"):
            o = d / f"{problem}_{transport}"
            p = subprocess.run([PYTHON, "-m", "bev_mdo", "pareto", str(EXAMPLES / f"{problem}.yaml"),
                                "--transport", transport, "--out", str(o),
                                *(["--domain-id", str(ros_domain)] if transport == "ros" else []),
                                "--pop", str(POP), "--generations", str(RUNS[problem][0]), "--seed", "1",
                                "--no-plots"], env=env, cwd=d, capture_output=True, text=True, timeout=300)
            assert p.returncode == 0, p.stderr[-3000:]
            out[problem, transport] = o
    return out


@pytest.mark.parametrize("problem", PROBLEMS)
def test_the_front_over_ros_matches_the_analytic_one_and_the_in_process_run(runs, problem):
    ros, inproc = runs[problem, "ros"], runs[problem, "inprocess"]
    check_front(problem, ros / "front.json")
    # same seed, deterministic evaluations, float64 unchanged on the wire: the same designs
    assert (ros / "front.csv").read_text() == (inproc / "front.csv").read_text()
    doc = json.loads((ros / "front.json").read_text())
    assert doc["transport"] == "ros" and doc["batches"] == RUNS[problem][0]
    assert not doc.get("recorder_failed")


@pytest.mark.parametrize("problem", PROBLEMS)
def test_the_recorder_wrote_every_generation_and_the_requests(runs, problem):
    from bev_mdo.bag.reader import open_bag
    from bev_mdo.studies.topologies import read_fronts

    bag = runs[problem, "ros"] / "bag"
    fronts = read_fronts(bag)
    generations = RUNS[problem][0]
    assert [(f["generation"], f["final"], f["topology"]) for f in fronts] == [
        (g, g == generations, "") for g in range(1, generations + 1)]
    topics = open_bag(bag).topics
    # the run's requests to its one discipline node and the node's results, beside the fronts
    assert any(t.endswith("request") for t in topics) and any(t.endswith("result") for t in topics), topics
