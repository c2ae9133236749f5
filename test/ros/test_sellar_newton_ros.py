"""Sellar MDF with the Newton-Raphson MDA (examples/sellar/sellar_mdf_newton.yaml) over ROS: the
in-process iterates to 1e-12 and the published optimum; one request wave per Newton step, the
partials travelling with the results."""
from __future__ import annotations

import pytest

from bev_mdo.config import load_config, resolve_disciplines  # noqa: E402
from bev_mdo.mdo.driver import run_optimization  # noqa: E402
from bev_mdo.mdo.evaluator import InProcessEvaluator  # noqa: E402
from bev_mdo.ros import coordinator_node  # noqa: E402
from bev_mdo.launcher import Launcher  # noqa: E402
from bev_mdo.processes import discipline_argv  # noqa: E402
from bev_mdo.testing import REPO, assert_same_iterates, ros_env  # noqa: E402

CONFIG = REPO / "examples" / "sellar" / "sellar_mdf_newton.yaml"
REF_F = 3.18339395


@pytest.fixture(scope="module")
def nodes(ros_domain, tmp_path_factory):
    launcher = Launcher(ros_env(ros_domain), log_dir=tmp_path_factory.mktemp("logs"))
    for name in ("sellar1", "sellar2", "sellar_obj"):
        launcher.add(name, discipline_argv(name, str(CONFIG)))
    yield launcher
    launcher.stop()
    for n in launcher.nodes:
        assert n.restarts == 0, f"{n.label} died: {n.log_path.read_text()[-2000:] if n.log_path else ''}"


def test_newton_mdf_over_ros_gives_the_in_process_iterates_and_the_reference(rclpy_context, nodes):
    config = load_config(CONFIG)
    assert config["mda"]["method"] == "newton"
    ros, stats = coordinator_node.run(config, context=rclpy_context)
    local = run_optimization(config, InProcessEvaluator(resolve_disciplines(config)))
    for r in (ros, local):
        assert r.feasible and r.objective == pytest.approx(REF_F, abs=1e-8)
        assert r.design["z1"] == pytest.approx(1.977639, abs=1e-5)
    assert ros.iterations == local.iterations
    assert_same_iterates(ros, local)
    assert ros.mda_evaluations == local.mda_evaluations
    assert stats["retried"] == 0


def test_warm_started_fused_newton_sends_the_in_process_waves_over_ros(rclpy_context, nodes, monkeypatch):
    """The example's tangent warm start with the objective fused into the Newton waves works over
    ROS: one request wave per Newton step, as many waves as in process, fewer than a cold, unfused
    Newton MDF, the same optimum."""
    from bev_mdo.ros import evaluator as ros_evaluator

    config = load_config(CONFIG)
    assert config["mda"]["warm_start"] == "tangent"
    config["mda"]["fuse_downstream"] = True
    waves = {"calls": 0}
    original = ros_evaluator.RosEvaluator.evaluate

    def counted(ev, calls, *a, **kw):
        if any(v.size for _, inputs in calls for v in inputs.values()):  # not the warm-up's empty wave
            waves["calls"] += 1
        return original(ev, calls, *a, **kw)

    monkeypatch.setattr(ros_evaluator.RosEvaluator, "evaluate", counted)
    ros, stats = coordinator_node.run(config, context=rclpy_context)
    local_ev = InProcessEvaluator(resolve_disciplines(config))
    local = run_optimization(config, local_ev)
    cold_cfg = load_config(CONFIG)
    cold_cfg["mda"].update(warm_start=False, fuse_downstream=False)
    cold_ev = InProcessEvaluator(resolve_disciplines(cold_cfg))
    cold = run_optimization(cold_cfg, cold_ev)
    assert waves["calls"] == local_ev.waves < cold_ev.waves
    assert ros.objective == local.objective and ros.design == local.design
    assert ros.objective == pytest.approx(cold.objective, rel=1e-10)
    assert stats["retried"] == 0
