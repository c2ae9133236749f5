"""A recorded optimisation, read back by independent tools; resume after the coordinator is killed."""
from __future__ import annotations

import json
import signal
import subprocess

import numpy as np
import pytest
import yaml


from bev_mdo.testing import PYTHON, REPO, ros_env  # noqa: E402


@pytest.fixture(scope="module")
def config_path(tmp_path_factory, ros_domain):
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["ros"] = {"domain_id": ros_domain, "discovery_wait_s": 60.0}
    p = tmp_path_factory.mktemp("cfg") / "leaf.yaml"
    p.write_text(yaml.safe_dump(raw))
    return p


@pytest.fixture(scope="module")
def recorded(config_path, tmp_path_factory, ros_domain):
    bag = tmp_path_factory.mktemp("bags") / "run"
    out = subprocess.run([PYTHON, "-m", "bev_mdo", "optimize", str(config_path), "--json", "--quiet",
                          "--bag", str(bag)], env=ros_env(ros_domain), cwd=bag.parent,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    return bag, json.loads(out.stdout)


def _counts_and_points(messages):
    """Per discipline: (requests, results, points requested) of one run.

    A data-flow request (/bev_mdo/mda_request) asks every discipline it names for all its
    points; a discipline skips the points a source failed, so the count holds when every
    point of the run succeeded (checked)."""
    req, res, pts = {}, {}, {}
    for topic, msg in messages:
        if topic == "/bev_mdo/mda_request":
            for d in msg.flow:
                req[d] = req.get(d, 0) + 1
                pts[d] = pts.get(d, 0) + msg.inputs.batch_size
        elif topic.endswith("/request"):
            req[msg.discipline] = req.get(msg.discipline, 0) + 1
            pts[msg.discipline] = pts.get(msg.discipline, 0) + msg.inputs.batch_size
        elif topic == "/bev_mdo/result" or topic.endswith("/mda_result"):
            res[msg.discipline] = res.get(msg.discipline, 0) + 1
            if topic.endswith("/mda_result"):
                assert all(msg.point_ok), f"a failed point in {msg.discipline}'s result: {msg.error}"
    return req, res, pts


def _check(messages, iterations, result):
    run = result["run_id"]
    ours = [(t, m) for t, m in messages if getattr(m, "run_id", run) == run]
    req, res, pts = _counts_and_points(ours)
    assert pts == result["discipline_evaluations"]  # every evaluated point is in the bag
    assert req == res  # every request has its result
    iterations = [m for m in iterations if m.run_id == run]
    assert iterations, "no iteration records"
    last = iterations[-1]
    names = list(last.design.names)
    design = dict(zip(names, np.asarray(last.design.values)))
    for k, v in result["design"].items():
        assert design[k] == pytest.approx(v, rel=1e-12)
    assert last.objective == pytest.approx(result["objective"], rel=1e-12)
    assert last.run_id == run and last.formulation == "mdf" and last.optimizer == "SLSQP"
    assert [m.iteration for m in iterations] == list(range(len(iterations)))
    # a request's iteration is the number of iteration records published before it was sent, so a
    # bag links each request to the records around it (header stamps: one clock, the coordinator's)
    def ns(header):
        return header.stamp.sec * 10**9 + header.stamp.nanosec

    records = [ns(m.header) for m in iterations]
    requests = [m for t, m in ours if t.endswith("request")]
    assert max(m.iteration for m in requests) >= 1
    for m in requests:
        assert m.iteration <= len(records)
        if m.iteration >= 1:
            assert ns(m.header) >= records[m.iteration - 1]
        if m.iteration < len(records):
            assert ns(m.header) <= records[m.iteration]


def test_rosbags_reads_the_bag_directory_and_the_bare_mcap(recorded):
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    bag, result = recorded
    mcap = next(bag.glob("*.mcap"))
    for path in (bag, mcap):
        with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
            msgs = [(c.topic, reader.deserialize(raw, c.msgtype)) for c, _, raw in reader.messages()]
        iterations = [m for t, m in msgs if t == "/bev_mdo/iteration"]
        _check(msgs, iterations, result)


def test_mcap_ros2_reads_the_bag_and_its_configuration(recorded):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    bag, result = recorded
    with open(next(bag.glob("*.mcap")), "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == "ros2"
        msgs = [(ch.topic, m) for _, ch, _, m in reader.iter_decoded_messages()]
        meta = {r.name: r.metadata for r in reader.iter_metadata()}
    iterations = [m for t, m in msgs if t == "/bev_mdo/iteration"]
    _check(msgs, iterations, result)
    assert "rosbag2" in meta and "serialized_metadata" in meta["rosbag2"]
    stored = yaml.safe_load(meta["bev_mdo"]["config_yaml"])
    assert stored["problem"]["design_variables"]["motor_kw"]["upper"] == 120
    assert meta["bev_mdo"]["run_id"] == result["run_id"]


def test_resume_after_the_coordinator_is_killed_reaches_the_same_optimum(config_path, tmp_path, ros_domain,
                                                                         recorded):
    from bev_mdo.bag.history import last_iterate
    from bev_mdo.config import discipline_entries, load_config
    from bev_mdo.launcher import Launcher
    from bev_mdo.processes import discipline_argv

    bag = tmp_path / "killed"
    env = ros_env(ros_domain)
    launcher = Launcher(env, log_dir=tmp_path / "logs")
    try:
        for e in discipline_entries(load_config(config_path)):
            launcher.add(e["name"], discipline_argv(e["name"], str(config_path)))
        launcher.add("recorder", [PYTHON, "-m", "bev_mdo.ros.run", "recorder_node", "--output", str(bag),
                                  "--config", str(config_path), "--run-id", "killed_run",
                                  "--ros-args", "-p", "discovery_period_s:=0.05"])
        # The coordinator as its own process (ros2 run bev_mdo coordinator_node); COBYLA takes dozens of
        # iterations, so it can be killed mid-run.
        proc = subprocess.Popen([PYTHON, "-m", "bev_mdo.ros.run", "coordinator_node", "--ros-args",
                                 "-p", f"config:={config_path}", "-p", "optimizer:=COBYLA",
                                 "-p", "recorders:=1", "-p", "run_id:=killed_run"],  # once its recorder listens
                                env=env, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        seen = []
        for line in proc.stdout:
            seen.append(line)
            if line.startswith("iter    8"):
                proc.send_signal(signal.SIGKILL)
                break
        proc.wait(timeout=60)
        assert proc.returncode == -signal.SIGKILL, "".join(seen[-20:])
    finally:
        launcher.stop()  # SIGINT: the recorder drains and closes the bag
    _, design, iteration = last_iterate(bag)
    assert iteration >= 1
    out = subprocess.run([PYTHON, "-m", "bev_mdo", "resume", str(bag), "--json", "--quiet",
                          "--output", str(tmp_path / "resumed")],
                         env=env, cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    resumed = json.loads(out.stdout)
    reference = recorded[1]  # the uninterrupted SLSQP run of the same problem
    for k, v in reference["design"].items():
        assert resumed["design"][k] == pytest.approx(v, rel=1e-4)
