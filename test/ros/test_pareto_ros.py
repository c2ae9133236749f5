"""``bev-mdo pareto --transport ros``: the same fronts as in process (same seed), the bag the
recorder wrote (every generation's ParetoFront, the run's requests and results), no node left."""
from __future__ import annotations

import json
import os
import signal
import subprocess
from pathlib import Path

import numpy as np
import pytest
import yaml


from bev_mdo.testing import PYTHON, REPO, ros_env  # noqa: E402

ROS_DOMAIN = 85
TOPOLOGY = "IWM-SA"  # not the default: the discipline nodes must get vehicle.topology too
ARGS = ["--topology", TOPOLOGY, "--pop", "8", "--generations", "2", "--seed", "3", "--no-plots"]
OBJ = ["energy_wh_per_km", "accel_time_0_100_s", "powertrain_cost_usd"]


@pytest.fixture(scope="module")
def runs(tmp_path_factory, ros_domain):
    """The same small NSGA-II run in process and over ROS (discipline nodes, recorder)."""
    d = tmp_path_factory.mktemp("pareto_ros")
    raw = yaml.safe_load((REPO / "config" / "topologies_artemis.yaml").read_text())
    raw["cycle"] = {"name": "nedc", "dt_s": 2.0}  # fast; the NEDC range integration dominates
    raw["ros"] = {**(raw.get("ros") or {}), "discovery_wait_s": 60.0}
    cfg = d / "cfg.yaml"
    cfg.write_text(yaml.safe_dump(raw))
    env = ros_env(ros_domain)
    out = {}
    for transport, extra in (("inprocess", []), ("ros", []), ("ros_pool", ["--instances", "energy=2"])):
        o = d / transport
        p = subprocess.run([PYTHON, "-m", "bev_mdo", "pareto", str(cfg), "--transport", transport.split("_")[0],
                            *(["--domain-id", str(ros_domain)] if transport != "inprocess" else []),
                            "--out", str(o), *ARGS, *extra],
                           env=env, cwd=d, capture_output=True, text=True, timeout=240)
        assert p.returncode == 0, p.stderr[-3000:]
        out[transport] = o
    return out


def _fronts(bag):
    """Every ParetoFront of a bag, read with rosbags: (generation, final, run_id, topology, {name: column})."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    fronts = []
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        conns = [c for c in reader.connections if c.topic == "/bev_mdo/pareto_front"]
        for c, _, raw in reader.messages(connections=conns):
            m = reader.deserialize(raw, c.msgtype)
            names, n = list(m.designs.names), int(m.designs.batch_size)
            v = np.asarray(m.designs.values, float).reshape(len(names), n)
            assert list(m.objectives) == OBJ
            fronts.append((int(m.generation), bool(m.final), m.run_id, m.topology,
                           {k: v[j] for j, k in enumerate(names)}))
    return fronts


def test_front_over_ros_equals_in_process(runs):
    ros, inproc = _fronts(runs["ros"] / "bag"), _fronts(runs["inprocess"] / "bag")
    assert [(g, f, t) for g, f, _, t, _ in ros] == [(1, False, TOPOLOGY), (2, True, TOPOLOGY)]
    assert [(g, f, t) for g, f, _, t, _ in inproc] == [(g, f, t) for g, f, _, t, _ in ros]
    for (g, _, _, _, a), (_, _, _, _, b) in zip(ros, inproc):
        assert a.keys() == b.keys() and "gear_ratio" not in a and "motor_kw" in a
        for k in a:
            # the evaluations are deterministic and float64 travels unchanged, so NSGA-II with the same
            # seed must pick the same designs and see the same outputs; only the transport differs
            np.testing.assert_allclose(a[k], b[k], rtol=1e-12, atol=0,
                                       err_msg=f"generation {g}, {k}: the front over ROS differs from the "
                                               f"in-process front of the same seed (rtol 1e-12)")
    final = ros[-1][4]
    assert len(final["energy_wh_per_km"]) >= 1
    from bev_mdo.mdo.pareto import non_dominated

    for *_, cols in ros:
        if len(cols["energy_wh_per_km"]):
            assert non_dominated(np.column_stack([cols[k] for k in OBJ])).all()
            assert np.all(cols["range_nedc_km"] >= 175.0)
    csv_ros = (runs["ros"] / f"pareto_{TOPOLOGY}.csv").read_text()
    assert csv_ros == (runs["inprocess"] / f"pareto_{TOPOLOGY}.csv").read_text()


def test_bag_holds_fronts_requests_and_results(runs):
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    summary = json.loads((runs["ros"] / "summary.json").read_text())
    run_id = summary["run_id"]
    assert summary["transport"] == "ros" and summary["node_restarts"] == {}
    assert {r for _, _, r, _, _ in _fronts(runs["ros"] / "bag")} == {run_id}
    requests, results = {}, set()
    with AnyReader([runs["ros"] / "bag"], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        for c, _, raw in reader.messages():
            if not (c.topic.endswith("request") or c.topic.endswith("result")):
                continue
            m = reader.deserialize(raw, c.msgtype)
            # a batch of no point is a start-up probe or warm-up MDA: it evaluates nothing, and the probes
            # sent before the recorder wait (startup.handshake) are in the bag only as far as it had matched
            batch = getattr(m, "inputs", None) if c.topic.endswith("request") else m.outputs
            if m.run_id != f"{run_id}-{TOPOLOGY}" or int(batch.batch_size) == 0:
                continue
            if c.topic.endswith("request"):
                # one request per discipline, or one data-flow request naming the disciplines in order
                requests[int(m.evaluation_id)] = list(getattr(m, "flow", None) or []) or [m.discipline]
            else:
                results.add((int(m.evaluation_id), m.discipline))
    assert requests, "no request of the run in the bag"
    disciplines = {"vehicle_mass", "energy", "cycle_range", "acceleration", "cost"}
    assert {d for ds in requests.values() for d in ds} == disciplines
    missing = [(e, d) for e, ds in requests.items() for d in ds if (e, d) not in results]
    assert not missing, f"requests recorded without their results: {missing}"
    from bev_mdo.bag.reader import read_config

    stored = yaml.safe_load(read_config(runs["ros"] / "bag"))  # the run's config, as given
    assert stored["name"] == "topologies_artemis" and stored["ros"]["domain_id"] == ROS_DOMAIN


def test_no_node_process_left(runs):
    """Every node the command started (disciplines, recorder) ran with a path inside its --out directory."""
    mine = str(runs["ros"])
    left = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            cmd = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        if mine in cmd:
            left.append((pid, cmd[:200]))
    assert not left, left
    logs = runs["ros"] / ".logs"
    assert (logs / "recorder.log").is_file() and (logs / TOPOLOGY / "energy.log").is_file()
    assert "recorded" in (logs / "recorder.log").read_text()  # it closed the bag on SIGINT


def test_pareto_with_an_energy_pool_gives_the_same_fronts(runs):
    """``--instances energy=2``: two energy nodes share every population (pool.py), the fronts and the
    CSV are those of the in-process run, and the bag shows both instances' work."""
    from bev_mdo.bag.reader import open_bag
    from bev_mdo.bag.report import instance_work

    pool, inproc = _fronts(runs["ros_pool"] / "bag"), _fronts(runs["inprocess"] / "bag")
    assert [(g, f) for g, f, *_ in pool] == [(g, f) for g, f, *_ in inproc]
    for (*_, a), (*_, b) in zip(pool, inproc):
        assert a.keys() == b.keys()
        for k in a:
            np.testing.assert_allclose(a[k], b[k], rtol=1e-12, atol=0, err_msg=k)
    assert (runs["ros_pool"] / f"pareto_{TOPOLOGY}.csv").read_text() == \
        (runs["inprocess"] / f"pareto_{TOPOLOGY}.csv").read_text()
    work = instance_work(open_bag(runs["ros_pool"] / "bag"))
    assert len(work["energy"]) == 2 and all(e["points"] > 0 for e in work["energy"].values()), work["energy"]
    assert len(work["vehicle_mass"]) == 1
    logs = runs["ros_pool"] / ".logs" / TOPOLOGY
    assert (logs / "energy#0.log").is_file() and (logs / "energy#1.log").is_file()


def test_a_recorder_killed_mid_study_is_reported_not_waited_for(runs, ros_domain, tmp_path):
    """SIGKILL of the recorder after the first generation (as `optimize` does): the study
    finishes with the in-process front, warns once, records the failure in summary.json, exits 3, and
    leaves a bag repaired on the spot (it opens in rosbags and in mcap, without its later fronts)."""
    from mcap.reader import make_reader
    from rosbags.rosbag2 import Reader

    from bev_mdo.testing import child_processes

    out = tmp_path / "killed"
    p = subprocess.Popen([PYTHON, "-m", "bev_mdo", "pareto", str(runs["inprocess"].parent / "cfg.yaml"),
                          "--transport", "ros", "--domain-id", str(ros_domain), "--out", str(out), *ARGS],
                         env=ros_env(ros_domain), cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True)
    err, killed = [], []
    for line in p.stderr:
        err.append(line)
        if not killed and line.strip().startswith("gen 1:"):
            killed = [pid for pid, cmd in child_processes(p.pid).items() if "recorder_node" in cmd]
            assert len(killed) == 1, child_processes(p.pid)
            os.kill(killed[0], signal.SIGKILL)  # a child of the study we started, by its id
    stdout = p.stdout.read()
    p.wait(timeout=240)
    err = "".join(err)
    assert killed, err[-3000:]
    assert p.returncode == 3, err[-3000:]
    assert err.count("warning: the recorder died") == 1 and "Traceback" not in err, err[-3000:]
    assert "wrote" in stdout
    summary = json.loads((out / "summary.json").read_text())
    assert "the recorder died (exit status -9)" in summary["recorder_failed"]
    assert (out / f"pareto_{TOPOLOGY}.csv").read_text() == \
        (runs["inprocess"] / f"pareto_{TOPOLOGY}.csv").read_text()
    with Reader(out / "bag") as reader:
        assert reader.message_count == sum(1 for _ in reader.messages()) > 0
    (mcap,) = sorted((out / "bag").glob("*.mcap"))
    with open(mcap, "rb") as f:
        assert make_reader(f).get_summary() is not None
    assert [(g, fin) for g, fin, *_ in _fronts(out / "bag")] in ([], [(1, False)])  # the final front is lost
