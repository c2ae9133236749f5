"""Sellar over ROS through the user-discipline interface only (examples/sellar/), and the CLI end to
end on a problem with no BEV variable.

The node processes get NO path to examples/sellar: each finds ``sellar_disciplines`` relative to the
config's folder, as the in-process path does. A loop graph: the start-up sends no data-flow request
(no node of a loop could answer it) and, on a healthy host, nothing is ever re-sent.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
import yaml


from bev_mdo.config import load_config, resolve_disciplines  # noqa: E402
from bev_mdo.mdo.driver import run_optimization  # noqa: E402
from bev_mdo.mdo.evaluator import InProcessEvaluator  # noqa: E402
from bev_mdo.ros import coordinator_node  # noqa: E402
from bev_mdo.launcher import Launcher  # noqa: E402
from bev_mdo.processes import discipline_argv  # noqa: E402
from bev_mdo.testing import REPO, assert_same_iterates, ros_env  # noqa: E402

EXAMPLE = REPO / "examples" / "sellar"
USER = REPO / "test" / "data" / "user_modules"
REF_F = 3.18339395


@pytest.fixture(scope="module")
def configs(tmp_path_factory):
    d = tmp_path_factory.mktemp("cfg")
    out = {"mdf": EXAMPLE / "sellar_mdf.yaml", "idf": EXAMPLE / "sellar_idf.yaml"}
    raw = yaml.safe_load((EXAMPLE / "sellar_mdf.yaml").read_text())
    raw["search_path"] = [str(EXAMPLE), str(USER)]
    raw["ros"] = {"timeout_s": 1.0, "retries": 1, "discovery_wait_s": 60.0}
    for name, cls in (("raises", "Raises"), ("hangs", "Hangs")):
        bad = {**raw, "disciplines": raw["disciplines"] + [{"name": name, "class": f"bad_disciplines:{cls}"}],
               "problem": {**raw["problem"], "constraints": {**raw["problem"]["constraints"], "w": {"upper": 1e6}}}}
        out[name] = d / f"{name}.yaml"
        out[name].write_text(yaml.safe_dump(bad, sort_keys=False))
    return out


@pytest.fixture(scope="module")
def nodes(ros_domain, configs, tmp_path_factory):
    env = ros_env(ros_domain)  # PYTHONPATH: the repository only, not examples/sellar
    launcher = Launcher(env, log_dir=tmp_path_factory.mktemp("logs"))
    for name in ("sellar1", "sellar2", "sellar_obj"):
        launcher.add(name, discipline_argv(name, str(configs["mdf"])))
    launcher.add("raises", discipline_argv("raises", str(configs["raises"])))
    launcher.add("hangs", discipline_argv("hangs", str(configs["hangs"])))
    yield launcher
    launcher.stop()
    for n in launcher.nodes:
        assert n.restarts == 0, f"{n.label} died: {n.log_path.read_text()[-2000:] if n.log_path else ''}"


def _inprocess(path, **kw):
    config = load_config(path)
    return run_optimization(config, InProcessEvaluator(resolve_disciplines(config)), **kw)


@pytest.mark.parametrize("optimizer,tol", [("SLSQP", 1e-7), ("COBYQA", 1e-6), ("COBYLA", 1e-6), ("trust-constr", 1e-6)])
@pytest.mark.parametrize("formulation", ["mdf", "idf"])
def test_sellar_over_ros_gives_the_in_process_iterates_and_the_reference(rclpy_context, nodes, configs,
                                                                          formulation, optimizer, tol):
    config = load_config(configs[formulation])
    ros, stats = coordinator_node.run(config, context=rclpy_context, optimizer=optimizer)
    local = _inprocess(configs[formulation], optimizer=optimizer)
    assert ros.feasible and ros.objective == pytest.approx(REF_F, rel=tol) and ros.verdict == "optimum"
    assert ros.first_order == {**local.first_order, "cost": ros.first_order["cost"]}
    assert ros.design["z1"] == pytest.approx(1.977639, abs=100 * tol)
    assert_same_iterates(ros, local)
    assert stats["retried"] == 0 and stats["data_flow_mdas"] == 0  # a loop: hub and spoke, nothing re-sent


def test_a_raising_user_discipline_is_named_and_the_run_still_ends_with_its_result(rclpy_context, nodes, configs):
    res, stats = coordinator_node.run(load_config(configs["raises"]), context=rclpy_context)
    assert not res.feasible
    assert res.error.startswith("raises: RuntimeError: the solver diverged") and "\n" not in res.error
    assert stats["retried"] == 0


def test_a_hanging_user_discipline_fails_once_then_at_once(rclpy_context, nodes, configs):
    """timeout 1 s, 1 retry: the first request to the hung node is re-sent once, then its points
    fail; every later request to it fails at once (no re-send), and the run ends with its result."""
    res, stats = coordinator_node.run(load_config(configs["hangs"]), context=rclpy_context)
    assert not res.feasible
    assert res.error == "hangs: no answer after 2 attempts of 1 s at point 0 (z1=5, x=1)"  # named as a raising one
    assert stats["retried"] == 1  # one request waited; the others failed without a wait
    assert res.iterations >= 0 and res.history


def _cli(*argv, env_domain, cwd, extra_env=None):
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env.update({"PYTHONPATH": str(REPO), "ROS_DOMAIN_ID": str(env_domain), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
                **(extra_env or {})})
    return subprocess.run([sys.executable, "-m", "bev_mdo", *map(str, argv)], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=600)


def test_cli_end_to_end_on_sellar_optimize_history_report_resume(ros_domain, tmp_path):
    """No BEV variable anywhere: optimize over ROS (domain from ROS_DOMAIN_ID), then history,
    report and resume from the bag; exit 0 and the JSON result every time."""
    bag = tmp_path / "bag"
    p = _cli("optimize", EXAMPLE / "sellar_mdf.yaml", "--json", "--bag", bag, env_domain=ros_domain, cwd=tmp_path)
    assert p.returncode == 0, p.stderr[-2000:]
    doc = json.loads(p.stdout)
    assert doc["objective"] == pytest.approx(REF_F, rel=1e-7) and doc["baseline"] is None
    # SLSQP's last gradient reused; its assembled totals confirmed by central differences (two batches), and
    # steps either side of the free variable look for a kink (one batch)
    assert doc["verdict"] == "optimum" and doc["first_order"]["derivatives_confirmed"]
    assert doc["first_order"]["cost"]["batches"] == 3
    assert doc["domain_id"] == ros_domain and doc["retried_requests"] == 0
    assert "retry" not in p.stderr and "overrides" not in p.stderr
    h = _cli("history", bag, "--csv", tmp_path / "h.csv", env_domain=ros_domain, cwd=tmp_path)
    assert h.returncode == 0, h.stderr
    rows = (tmp_path / "h.csv").read_text().splitlines()
    assert len(rows) - 1 == doc["iterations"] + 1  # one row per record, iterations count the records
    r = _cli("report", bag, env_domain=ros_domain, cwd=tmp_path)
    assert r.returncode == 0 and (bag / "report.md").is_file(), r.stderr
    s = _cli("resume", bag, "--transport", "inprocess", "--json", env_domain=ros_domain, cwd=tmp_path)
    assert s.returncode == 0, s.stderr
    assert json.loads(s.stdout)["objective"] == pytest.approx(REF_F, rel=1e-7)


def test_multi_start_over_ros_is_one_bag_of_every_start(ros_domain, tmp_path):
    bag = tmp_path / "bag"
    p = _cli("optimize", EXAMPLE / "sellar_mdf.yaml", "--json", "--bag", bag, "--starts", "3",
             env_domain=ros_domain, cwd=tmp_path)
    assert p.returncode == 0, p.stderr[-2000:]
    doc = json.loads(p.stdout)
    ms = doc["multistart"]
    assert ms["starts"] == 3 and ms["reached_best"] >= 1 and doc["objective"] == pytest.approx(REF_F, rel=1e-7)
    h = _cli("history", bag, "--csv", tmp_path / "h.csv", env_domain=ros_domain, cwd=tmp_path)
    assert h.returncode == 0, h.stderr
    rows = (tmp_path / "h.csv").read_text().splitlines()
    assert len(rows) - 1 == sum(r["iterations"] + 1 for r in ms["results"])  # every start's records


def test_a_config_domain_overrides_the_environment_and_says_so(ros_domain, tmp_path):
    raw = yaml.safe_load((EXAMPLE / "sellar_mdf.yaml").read_text())
    raw["ros"] = {"domain_id": ros_domain}
    raw["search_path"] = [str(EXAMPLE)]
    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump(raw))
    other = (ros_domain + 1) % 233
    p = _cli("optimize", cfg, "--json", "--no-record", env_domain=other, cwd=tmp_path)
    assert p.returncode == 0, p.stderr[-2000:]
    assert json.loads(p.stdout)["domain_id"] == ros_domain
    assert not (tmp_path / "bags").exists() and "logs" not in json.loads(p.stdout)  # --no-record keeps nothing
    notes = [ln for ln in p.stderr.splitlines() if "overrides" in ln]
    assert notes == [f"bev-mdo: ros.domain_id {ros_domain} of the config overrides ROS_DOMAIN_ID={other} "
                     "of the environment"]
