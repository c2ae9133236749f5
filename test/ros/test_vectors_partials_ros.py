"""Vector variables and analytic partials over ROS: the vector Sellar problem (a loop, vectors,
partials) gives the in-process iterates, in MDF and IDF, with partials and with finite
differences; a discipline returning one value for a whole batch is named in one line."""
from __future__ import annotations

import sys

import pytest
import yaml


from bev_mdo.config import load_config, resolve_disciplines, run_settings  # noqa: E402
from bev_mdo.mdo.driver import run_optimization  # noqa: E402
from bev_mdo.mdo.evaluator import InProcessEvaluator  # noqa: E402
from bev_mdo.mdo.vectors import ShapeError  # noqa: E402
from bev_mdo.ros.client import make_ros_evaluator  # noqa: E402
from bev_mdo.launcher import Launcher  # noqa: E402
from bev_mdo.processes import discipline_argv  # noqa: E402
from bev_mdo.testing import REPO, assert_same_iterates, ros_env  # noqa: E402
from examples.sellar_vector import REFERENCE  # noqa: E402

SELLAR = REPO / "examples" / "sellar_vector.yaml"
GOLINSKI = REPO / "examples" / "golinski.yaml"
MDO_TESTS = REPO / "test" / "mdo"
sys.path.insert(0, str(MDO_TESTS))  # vector_toys, for the bad discipline
NAMES = ["sellar_dis1", "sellar_dis2", "sellar_functions"]


@pytest.fixture(scope="module")
def configs(ros_domain, tmp_path_factory):
    d = tmp_path_factory.mktemp("cfg")
    raw = yaml.safe_load(SELLAR.read_text())
    raw["ros"] = {"timeout_s": 5.0, "retries": 3, "discovery_wait_s": 60.0, "domain_id": ros_domain}
    out = {}
    for mode in ("analytic", "fd"):
        raw["optimizer"]["derivatives"] = mode
        (d / f"{mode}.yaml").write_text(yaml.safe_dump(raw, sort_keys=False))
        out[mode] = str(d / f"{mode}.yaml")
    bad = yaml.safe_load(SELLAR.read_text())
    bad["disciplines"][0] = {"name": "sellar_dis1", "class": "vector_toys:ScalarForBatch"}
    bad["ros"] = {"timeout_s": 5.0, "retries": 0, "discovery_wait_s": 60.0, "domain_id": ros_domain}
    (d / "bad.yaml").write_text(yaml.safe_dump(bad, sort_keys=False))
    out["bad"] = str(d / "bad.yaml")
    gol = yaml.safe_load(GOLINSKI.read_text())
    gol["ros"] = raw["ros"]
    (d / "golinski.yaml").write_text(yaml.safe_dump(gol, sort_keys=False))
    out["golinski"] = str(d / "golinski.yaml")
    return out


@pytest.fixture(scope="module")
def nodes(ros_domain, configs, tmp_path_factory):
    env = ros_env(ros_domain)
    env["PYTHONPATH"] = f"{MDO_TESTS}:{REPO}:{env['PYTHONPATH']}"
    launcher = Launcher(env, log_dir=tmp_path_factory.mktemp("logs"))
    for name in NAMES:  # the nodes compute partials only when a request asks: one set serves both modes
        launcher.add(name, discipline_argv(name, configs["analytic"]))
    for name in ("gear", "shaft1", "shaft2", "weight"):
        launcher.add(name, discipline_argv(name, configs["golinski"]))
    yield launcher
    launcher.stop()
    for n in launcher.nodes:
        assert n.restarts == 0, f"{n.label} died: {n.log_path.read_text()[-2000:] if n.log_path else ''}"


def _over_ros(cfg, formulation):
    """run_optimization through the nodes (the ROS evaluator of `bev-mdo evaluate --attach`; no warm-up,
    whose data-flow MDAs a graph with a loop does not answer)."""
    ev = make_ros_evaluator(cfg, node_name="vector_test_client")
    try:
        return run_optimization(run_settings(cfg), ev, formulation=formulation), ev.inner.retried
    finally:
        ev.close()


@pytest.mark.parametrize("formulation", ["mdf", "idf"])
@pytest.mark.parametrize("mode", ["analytic", "fd"])
def test_vector_sellar_over_ros_gives_the_in_process_iterates(ros_domain, nodes, configs, mode, formulation):
    cfg = load_config(configs[mode])
    ros, retried = _over_ros(cfg, formulation)
    local = run_optimization(cfg, InProcessEvaluator(resolve_disciplines(cfg)), formulation=formulation)
    assert ros.feasible and local.feasible
    assert ros.objective == pytest.approx(REFERENCE["objective"], abs=1e-6)
    assert len(ros.history) == len(local.history)
    assert all(a["design"].keys() == {"z[0]", "z[1]", "x"} for a in ros.history)
    assert_same_iterates(ros, local)
    assert retried == 0


@pytest.mark.parametrize("formulation", ["mdf", "idf"])
def test_golinski_over_ros_reaches_its_reference_with_the_in_process_iterates(ros_domain, nodes, configs,
                                                                              formulation):
    from examples.golinski import REFERENCE as GOL

    cfg = load_config(configs["golinski"])
    ros, retried = _over_ros(cfg, formulation)
    local = run_optimization(cfg, InProcessEvaluator(resolve_disciplines(cfg)), formulation=formulation)
    assert ros.feasible and ros.objective == pytest.approx(GOL["weight"], abs=0.01)
    assert ros.design["x_shaft2[1]"] == pytest.approx(GOL["x_shaft2"][1], abs=1e-4)
    assert [h["design"] for h in ros.history] == [h["design"] for h in local.history]
    assert ros.discipline_evaluations == local.discipline_evaluations and retried == 0


def test_a_scalar_for_a_whole_batch_is_named_in_one_line_over_ros(ros_domain, nodes, configs, tmp_path):
    """Runs last: stops the module's nodes and serves the same names with the bad dis1."""
    nodes.stop()
    launcher = Launcher(nodes.env, log_dir=tmp_path)
    try:
        for name in NAMES:
            launcher.add(name, discipline_argv(name, configs["bad"]))
        with pytest.raises(ShapeError, match=r"^discipline 'sellar_dis1': output 'y1' has shape \(\), expected \("):
            _over_ros(load_config(configs["bad"]), "mdf")  # the in-process line (it was a failed point over ROS)
    finally:
        launcher.stop()
