"""Sobieski's SSBJ over ROS through the user-discipline interface only (examples/ssbj/): four
discipline nodes, vector variables on the wire, a loop of three disciplines iterated hub and
spoke, analytic partials on the wire. MDF and IDF over ROS give the in-process iterates to the
last digit, and the reference optimum (test/mdo/test_ssbj.py holds the in-process checks and
the sources).

The node processes get no path to examples/ssbj: each finds ``ssbj_disciplines`` relative to the
config's folder.
"""
from __future__ import annotations

import pytest
import yaml


from bev_mdo.config import load_config, resolve_disciplines  # noqa: E402
from bev_mdo.mdo.driver import run_optimization  # noqa: E402
from bev_mdo.mdo.evaluator import InProcessEvaluator  # noqa: E402
from bev_mdo.ros import coordinator_node  # noqa: E402
from bev_mdo.launcher import Launcher  # noqa: E402
from bev_mdo.processes import discipline_argv  # noqa: E402
from bev_mdo.testing import REPO, assert_same_iterates, ros_env  # noqa: E402

EXAMPLE = REPO / "examples" / "ssbj"
OPTIMUM_RANGE = 3963.3800123  # see test/mdo/test_ssbj.py
DISCIPLINES = ("structure", "aerodynamics", "propulsion", "mission")


@pytest.fixture(scope="module")
def nodes(ros_domain, tmp_path_factory):
    launcher = Launcher(ros_env(ros_domain), log_dir=tmp_path_factory.mktemp("logs"))
    for name in DISCIPLINES:
        launcher.add(name, discipline_argv(name, str(EXAMPLE / "ssbj_mdf.yaml")))
    yield launcher
    launcher.stop()
    for n in launcher.nodes:
        assert n.restarts == 0, f"{n.label} died: {n.log_path.read_text()[-2000:] if n.log_path else ''}"


@pytest.mark.parametrize("formulation,derivatives", [("mdf", "analytic"), ("idf", "analytic"), ("mdf", "fd")])
def test_ssbj_over_ros_gives_the_in_process_iterates_and_the_reference(rclpy_context, nodes, formulation,
                                                                       derivatives):
    """analytic: the configs' default (every discipline has partials; over ROS they travel with
    the results); fd: batched finite-difference stencils of whole MDAs."""
    raw = yaml.safe_load((EXAMPLE / f"ssbj_{formulation}.yaml").read_text())
    raw["optimizer"]["derivatives"] = derivatives
    raw["search_path"] = [str(EXAMPLE)]
    config = load_config(raw)
    ros, stats = coordinator_node.run(config, context=rclpy_context)
    local = run_optimization(config, InProcessEvaluator(resolve_disciplines(config)))
    assert ros.feasible and ros.maximize
    assert ros.objective == pytest.approx(OPTIMUM_RANGE, abs=1e-3)
    assert len(ros.history) == len(local.history) > 5
    assert all(list(a["design"]) == list(local.design) for a in ros.history)  # x_shared[0] .. x_3, by element
    assert_same_iterates(ros, local)
    assert ros.design == pytest.approx(local.design, rel=1e-12, abs=1e-12)
    assert ros.mda_evaluations == local.mda_evaluations
    assert stats["retried"] == 0 and stats["data_flow_mdas"] == 0  # a loop: hub and spoke, nothing re-sent
