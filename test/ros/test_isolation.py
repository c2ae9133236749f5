"""Runs never mix: answers come only from the run's own disciplines.

Three node suites with three different configurations (the Leaf, drag area 0.8, WLTC) and a
fourth, foreign suite (drag area 0.9) serve one domain. Ten rounds of three concurrent
optimisations, one per configuration: each reports exactly its own in-process optimum (1e-9),
and every run refuses the instances of the other configurations (naming the difference) while
the foreign nodes answer nothing. Then three concurrent `bev-mdo optimize` runs, whose nodes
are bound to their run and whose messages are signed with a per-run key by default, on the
same crowded domain. The problem is kept small (three disciplines, SLSQP, few iterations) so the
rounds stay short; the in-process references are computed once.
"""
from __future__ import annotations

import json
import signal
import subprocess
import threading

import numpy as np
import pytest
import yaml

import rclpy

from bev_mdo.config import load_config, resolve_disciplines  # noqa: E402
from bev_mdo.mdo.driver import run_optimization  # noqa: E402
from bev_mdo.mdo.evaluator import InProcessEvaluator  # noqa: E402
from bev_mdo import protocol  # noqa: E402
from bev_mdo.ros import coordinator_node  # noqa: E402
from bev_mdo.binding import tag_for  # noqa: E402
from bev_mdo.ros.status import NodeStatsListener  # noqa: E402
from bev_mdo.ros.evaluator import RosEvaluator, _Pending  # noqa: E402
from bev_mdo.launcher import Launcher  # noqa: E402
from bev_mdo.processes import discipline_argv  # noqa: E402
from bev_mdo.testing import PYTHON, REPO, ros_env  # noqa: E402

NAMES = ["vehicle_mass", "energy", "range"]
VARIANTS = {"leaf": None, "drag08": ("vehicle", "drag_area_m2", 0.8), "wltc": ("cycle", "name", "wltc_class3")}
FOREIGN = ("vehicle", "drag_area_m2", 0.9)
ROUNDS = 10


def _raw(change):
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["disciplines"] = list(NAMES)
    raw["problem"]["constraints"] = {"range_km": {"lower": 210}}
    # a box whose designs all follow the cycle: with range alone the optimum ran to 40 kW at 11:1, which
    # cannot reach the NEDC's 120 km/h (motor over its speed limit) nor follow the WLTC (verdict infeasible)
    raw["problem"]["design_variables"]["motor_kw"]["lower"] = 60.0
    raw["problem"]["design_variables"]["gear_ratio"]["upper"] = 9.0
    raw["optimizer"] = {"name": "SLSQP", "options": {"maxiter": 6}}
    raw["ros"] = {"timeout_s": 5.0, "retries": 3, "discovery_wait_s": 60.0}
    if change:
        raw[change[0]][change[1]] = change[2]
    return raw


@pytest.fixture(scope="module")
def configs(tmp_path_factory):
    d = tmp_path_factory.mktemp("iso")
    out = {}
    for name, change in {**VARIANTS, "foreign": FOREIGN}.items():
        p = d / f"{name}.yaml"
        p.write_text(yaml.safe_dump(_raw(change), sort_keys=False))
        out[name] = str(p)
    return out


@pytest.fixture(scope="module")
def references(configs):
    refs = {}
    for name in VARIANTS:
        c = load_config(configs[name])
        refs[name] = run_optimization(c, InProcessEvaluator(resolve_disciplines(c)))
    objectives = sorted(r.objective for r in refs.values())
    assert min(np.diff(objectives)) > 1.0  # the three optima really differ: a mix-up would show
    return refs


@pytest.fixture(scope="module")
def suites(ros_domain, rclpy_context, configs, tmp_path_factory):
    la = Launcher(ros_env(ros_domain), log_dir=tmp_path_factory.mktemp("logs"))
    try:
        for suite in (*VARIANTS, "foreign"):
            for n in NAMES:
                la.add(f"{n}_{suite}", discipline_argv(n, configs[suite], instance=suite))
        # as a run's own nodes are: a node whose participant goes silent while its process lives (the
        # Fast DDS participant hangs; once in CI a suite's range node vanished for every later run) is
        # killed and restarted by the watchdog, and only such restarts are allowed (checked below)
        la.supervise(watch_hangs=True)
        node = rclpy.create_node("wait_for_suites", context=rclpy_context)
        stats = NodeStatsListener(node)
        try:
            assert stats.wait(lambda s: len(s.latest) == 4 * len(NAMES), 90), sorted(stats.latest)
        finally:
            stats.close()
            node.destroy_node()
        yield la
    finally:
        la.stop()
    assert all(n.restarts == n.hangs for n in la.nodes), [(n.label, n.restarts, n.hangs) for n in la.nodes]


def _concurrent(configs, round_no: int) -> dict:
    """One optimisation per variant, all at once, each in its own rclpy context."""
    out, errors = {}, []
    start = threading.Barrier(len(VARIANTS))

    def one(name):
        ctx = rclpy.context.Context()
        rclpy.init(context=ctx)
        try:
            start.wait()
            out[name] = coordinator_node.run(load_config(configs[name]), run_id=f"{name}-{round_no}", context=ctx)
        except BaseException as exc:  # noqa: BLE001 - reported below
            errors.append(f"{name}: {exc!r}")
        finally:
            rclpy.shutdown(context=ctx)

    threads = [threading.Thread(target=one, args=(n,)) for n in VARIANTS]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=300)
    assert not errors, errors
    return out


def _same(design, ref):
    for k, v in ref.items():
        assert design[k] == pytest.approx(v, rel=1e-9, abs=1e-9), k


def test_concurrent_runs_of_different_configs_each_get_their_own_optimum(configs, references, suites,
                                                                          rclpy_context):
    refused_total = 0
    foreign_refused = {name: set() for name in VARIANTS}
    for r in range(ROUNDS):
        got = _concurrent(configs, r)
        for name, (res, stats) in got.items():
            _same(res.design, references[name].design)
            assert res.objective == pytest.approx(references[name].objective, rel=1e-9), (r, name)
            # no instance of this run's configuration was refused; those of other configurations that
            # declared themselves before the run ended were, naming what differs
            refused = stats["refused_instances"]
            assert not [k for k in refused if k.endswith(f"_{name}")], refused
            for k, why in refused.items():
                if "foreign" in k:
                    assert "vehicle.drag_area_m2: 0.9" in why, why
                    foreign_refused[name].add(k.split(" ")[0])
            assert stats["dropped"].get("refused_instance", 0) == len(refused)
            assert not stats["dropped"].get("fingerprint")
            refused_total += len(refused)
    for name in VARIANTS:  # every foreign node was refused by every configuration's runs
        assert foreign_refused[name] == set(NAMES), foreign_refused
    # the foreign suite saw every run's requests and answered none of them
    node = rclpy.create_node("foreign_stats", context=rclpy_context)
    stats = NodeStatsListener(node)
    try:
        assert stats.wait(lambda s: all(f"{n}_node_foreign" in s.latest for n in NAMES), 30)
        for n in NAMES:
            c = stats.latest[f"{n}_node_foreign"]["counts"]
            assert c.get("answered", 0) == 0 and c.get("received", 0) == 0, c
        roots = stats.latest["vehicle_mass_node_foreign"]["counts"]
        assert roots.get("ignored.fingerprint", 0) > 0, roots  # it read the MDA requests and ignored them
    finally:
        stats.close()
        node.destroy_node()
    assert refused_total >= ROUNDS * len(VARIANTS) * len(NAMES)  # at least the foreign suite, every run


def test_a_result_with_another_binding_is_dropped_and_counted(rclpy_context, configs):
    config = load_config(configs["leaf"])
    node = rclpy.create_node("binding_probe", context=rclpy_context)
    ev = RosEvaluator(node, run_id="probe", config=config)
    try:
        def request(eid):
            req = protocol.request("probe", eid, "vehicle_mass")
            req.header.frame_id = ev._tag(["vehicle_mass"])
            return req

        def result(eid, frame_id):
            res = protocol.result()
            res.header.frame_id = frame_id
            res.run_id, res.evaluation_id, res.discipline, res.instance = "probe", eid, "vehicle_mass", "x"
            res.point_ok = np.ones(1, bool)
            res.outputs = protocol.batch({"vehicle_mass_kg": np.array([1500.0])})
            return res

        assert ev._tag(["vehicle_mass"]) == tag_for(config, ["vehicle_mass"])
        foreign = tag_for(load_config(configs["foreign"]), ["vehicle_mass"])
        assert foreign != ev._tag(["vehicle_mass"])
        for eid in (1, 2):
            ev._pending[(eid, "vehicle_mass")] = _Pending(eid, "vehicle_mass", request(eid), 1, 0)
        ev._on_result(result(1, foreign))  # answered for the drag-0.9 configuration
        ev._on_result(result(1, ""))       # answered without any binding
        ev._on_result(result(2, ev._tag(["vehicle_mass"])))
        assert dict(ev.dropped) == {"fingerprint": 2}
        assert [a[0] for a in ev.accepted] == [2]
        assert (1, "vehicle_mass") in ev._pending  # still waiting for its own configuration's answer
    finally:
        ev.close()
        node.destroy_node()


def _summary(out: str) -> str:
    """What a failed run's JSON says about its messages (the run finished: it printed its result)."""
    try:
        res = json.loads(out)
    except ValueError:
        return "(no JSON on stdout)"
    return json.dumps({k: res.get(k) for k in ("message", "logs", "dropped_messages", "retried_requests",
                                                "discipline_errors", "fd_failures", "refused_instances")})


def _unready(run_dir) -> str:
    """The logs of the runs' nodes that never said they serve (with the stacks the launcher dumps)."""
    out = []
    for log in sorted(run_dir.glob("bags/*/logs/*.log")):
        text = log.read_text(errors="replace")
        if "serving" not in text:
            out.append(f"--- {log.relative_to(run_dir)} (never served)\n{text[-3000:]}")
    return "\n".join(out)


def _cli_trio(configs, references, ros_domain, cwd) -> dict:
    """Three `bev-mdo optimize` at once, one per configuration, each checked: its own optimum, signed with
    its own per-run key (beside its bag, readable by no one else), no node crashed, and only the
    standalone suites' unbound nodes refused. Returns each run's JSON."""
    cwd.mkdir()
    env = ros_env(ros_domain)
    procs = {name: subprocess.Popen(
        [PYTHON, "-m", "bev_mdo", "optimize", configs[name], "--domain-id", str(ros_domain), "--no-record",
         "--bag", f"bags/{name}", "--json", "--quiet"],  # --no-record with --bag: its logs and key kept there
        cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        for name in VARIANTS}
    outs = {}
    for name, p in procs.items():
        try:
            out, err = p.communicate(timeout=240)
        except subprocess.TimeoutExpired:  # where it waits: every thread's stack (bev_mdo.stacks), then kill
            p.send_signal(signal.SIGUSR1)
            try:
                out, err = p.communicate(timeout=5)
            except subprocess.TimeoutExpired:
                p.kill()
                out, err = p.communicate()
        assert p.returncode == 0, f"{name}: exit {p.returncode}\n{_summary(out)}\n{_unready(cwd)}\n" + "\n".join(
            line for line in err.splitlines() if "refused '" not in line)[-6000:]
        outs[name] = json.loads(out)
    for name, out in outs.items():
        why = {k: out.get(k) for k in ("message", "iterations", "result_iteration", "discipline_errors",
                                       "dropped_messages", "retried_requests", "refused_instances",
                                       "fd_failures", "max_violation", "mda_evaluations")}
        assert out["design"] == pytest.approx(references[name].design, rel=1e-9, abs=1e-9), (name, why)
        assert out["objective"] == pytest.approx(references[name].objective, rel=1e-9)
        assert out["signing"] == "per-run key"
        # the other runs' own nodes (bound to their run, signing with its key) are another job's, ignored
        # and counted as info_other_run; only the standalone suites' unbound nodes are refused (they were
        # reported as 'forged declaration' before, alarming a user who runs two jobs on one domain)
        assert all(k.rsplit("_", 1)[-1] in (*VARIANTS, "foreign") for k in out["refused_instances"]), (
            name, out["refused_instances"])
        # no node crashed; a node the watchdog found hung in the middleware (Fast DDS deadlock under
        # overload, ros/watchdog.py) is restarted and counted in both, and the run still got its answer
        assert out["node_restarts"] == out.get("node_hangs", {}), (name, why, out.get("node_hangs"))
    keys = list(cwd.glob("bags/.keys/*/sign.key"))
    assert len(keys) == len(outs)  # one per-run key each, beside (not inside) its bag
    for key in keys:
        assert key.stat().st_mode & 0o077 == 0  # never readable by others
    return outs


def test_concurrent_cli_runs_are_bound_to_their_run_and_signed(configs, references, suites, ros_domain,
                                                                tmp_path):
    """Three `bev-mdo optimize` at once on the crowded domain: each launches its own nodes (bound to its
    run id, signing with a fresh per-run key) and prints its own optimum. The standalone suites of the
    same configurations answer too, unsigned: those answers are dropped and counted, and the foreign
    suite is refused by name.

    Whether a standalone suite hears a run at all is a race between discovery and the run's end: a run
    takes 10-150 ms once its own nodes serve, and in 18 runs on this host 4 heard no standalone answer;
    once in CI none of three did. So up to three trios run, each checked in full (_cli_trio), until the
    suites were heard; the drop and the refusal must then be there."""
    attempts = []
    for attempt in range(3):
        outs = _cli_trio(configs, references, ros_domain, tmp_path / f"trio{attempt}")
        unsigned = sum(out["dropped_messages"].get("unsigned", 0) for out in outs.values())
        foreign = [n for n, out in outs.items() if any("foreign" in k for k in out["refused_instances"])]
        attempts.append({n: (o["dropped_messages"], sorted(o["refused_instances"])) for n, o in outs.items()})
        if unsigned > 0 and foreign:
            break
    # the standalone suite of a configuration read the signed requests and answered unsigned: dropped,
    # counted; and the foreign suite (another config under the same names) was refused where it was seen
    assert unsigned > 0 and foreign, attempts
