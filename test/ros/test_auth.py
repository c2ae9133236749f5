"""Message authentication (HMAC-SHA256 with a shared key file).

Unit tests of the signer; then discipline nodes started with `ros.sign_key_file`:
a signed optimisation equals the in-process one, and unsigned, forged, expired and
replayed requests (published by an attacker node) and results (fed to the
coordinator's evaluator) are dropped and counted under those names.
"""
from __future__ import annotations

import secrets
import time

import numpy as np
import pytest
import yaml

import rclpy

from bev_mdo.config import load_config, resolve_disciplines  # noqa: E402
from bev_mdo.mdo.driver import run_optimization  # noqa: E402
from bev_mdo.mdo.evaluator import InProcessEvaluator  # noqa: E402
from bev_mdo import protocol  # noqa: E402
from bev_mdo.ros import coordinator_node  # noqa: E402
from bev_mdo.protocol.signing import AuthError, Signer, read_key  # noqa: E402
from bev_mdo.ros.common import REQUEST_QOS, request_topic, stamp  # noqa: E402
from bev_mdo.ros.status import NodeStatsListener  # noqa: E402
from bev_mdo.ros.evaluator import RosEvaluator, _Pending  # noqa: E402
from bev_mdo.launcher import Launcher  # noqa: E402
from bev_mdo.processes import discipline_argv  # noqa: E402
from bev_mdo.binding import tag_for  # noqa: E402
from bev_mdo.ros_settings import validate_ros  # noqa: E402
from bev_mdo.testing import REPO, ros_env  # noqa: E402
from bev_mdo_msgs.msg import EvaluationRequest, EvaluationResult  # noqa: E402

BUILTINS = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost"]


# This module's own ROS domain, in the 80-89 block of the fault tests (see test/conftest.py).
ROS_DOMAIN = 82
KEY = secrets.token_hex(32)


TAG = tag_for(load_config(REPO / "config" / "leaf_nedc.yaml"), ["vehicle_mass"])  # the binding nodes serve


def _request(run_id="r1", eid=1, attempt=0, t_ns=None):
    req = EvaluationRequest()
    stamp(req.header, t_ns)
    req.header.frame_id = TAG
    req.run_id, req.evaluation_id, req.attempt, req.discipline = run_id, eid, attempt, "vehicle_mass"
    protocol.to_named_array({"motor_kw": np.array([80.0]), "battery_kwh": np.array([24.0])}, req.inputs)
    return req


# -- the signer alone -------------------------------------------------------------------
def test_signed_request_verifies_once_then_is_a_replay():
    s = Signer(KEY.encode())
    req = _request()
    s.sign_request(req)
    assert len(req.signature) == 64
    assert s.verify_request(req) is None
    assert s.verify_request(req) == "replayed"


def test_unsigned_forged_tampered_and_expired_are_named():
    s, other = Signer(KEY.encode()), Signer(b"another key of 32 bytes........")
    assert s.verify_request(_request()) == "unsigned"
    req = _request()
    other.sign_request(req)
    assert s.verify_request(req) == "forged"
    for field, value in (("evaluation_id", 2), ("run_id", "r2"), ("attempt", 1), ("discipline", "energy"),
                         ("iteration", 4), ("sequence", 12), ("partials", True), ("flow", ["energy"])):
        req = _request()
        s.sign_request(req)
        setattr(req, field, value)
        assert s.verify_request(req) == "forged", field
    req = _request()
    s.sign_request(req)
    req.inputs.values[0] = 81.0  # a changed value
    assert s.verify_request(req) == "forged"
    for dt in (-31e9, +31e9):  # too old, or from the far future
        req = _request(t_ns=time.time_ns() + int(dt))
        s.sign_request(req)
        assert s.verify_request(req) == "expired"


def test_a_retry_is_not_a_replay():
    s = Signer(KEY.encode())
    a, b = _request(attempt=0), _request(attempt=1)
    s.sign_request(a)
    s.sign_request(b)
    assert s.verify_request(a) is None and s.verify_request(b) is None


def test_result_fields_are_covered():
    s = Signer(KEY.encode())
    res = EvaluationResult()
    stamp(res.header)
    res.run_id, res.evaluation_id, res.discipline, res.instance = "r1", 3, "energy", "/energy_node"
    res.point_ok = [True, False]
    protocol.to_named_array({"energy_wh_per_km": np.array([120.0, np.nan])}, res.outputs)
    res.error_points, res.error_reasons, res.error_inputs = [1], ["energy: ValueError: no"], ["v=1"]
    s.sign_result(res)
    for field, value in (("status", 1), ("error", "x"), ("point_ok", [False, False]), ("compute_time_s", 1.0),
                         ("error_points", [0]), ("error_reasons", ["energy: ok really"]), ("error_inputs", ["v=2"])):
        r2 = EvaluationResult()
        for f in ("header", "run_id", "evaluation_id", "discipline", "instance", "point_ok", "outputs",
                  "signature", "status", "error", "compute_time_s", "error_points", "error_reasons", "error_inputs"):
            setattr(r2, f, getattr(res, f))
        setattr(r2, field, value)
        assert s.verify_result(r2) == "forged", field
    assert s.verify_result(res) is None


def test_key_file_errors_never_show_the_key(tmp_path):
    short = tmp_path / "short.key"
    short.write_text("tooshort")
    short.chmod(0o600)
    with pytest.raises(AuthError, match="key shorter than") as exc:
        read_key(short)
    assert "tooshort" not in str(exc.value)
    with pytest.raises(AuthError, match="cannot read"):
        read_key(tmp_path / "absent.key")
    assert "KEY" not in repr(Signer(KEY.encode())) and KEY not in repr(Signer(KEY.encode()))


@pytest.mark.parametrize("mode", [0o644, 0o640, 0o604])
def test_a_key_file_others_may_read_is_refused_as_ssh_refuses_a_private_key(tmp_path, mode):
    """A user trial: a key file of mode 0644 was used without a word; other users could sign as the run."""
    key = tmp_path / "team.key"
    key.write_text(KEY)
    key.chmod(mode)
    with pytest.raises(AuthError) as exc:
        read_key(key, "--key-file")
    assert str(exc.value) == (f"--key-file '{key}': mode {mode:04o} lets other users read the key; "
                              f"run: chmod 600 {key}")
    assert KEY not in str(exc.value)
    key.chmod(0o600)
    assert read_key(key) == KEY.encode()


def test_the_resolved_config_holds_only_the_path(tmp_path, monkeypatch):
    (tmp_path / "k").write_text(KEY)
    monkeypatch.chdir(tmp_path)
    ros = validate_ros({"sign_key_file": "k"})
    assert ros["sign_key_file"] == str(tmp_path / "k")
    assert KEY not in yaml.safe_dump(ros)


# -- nodes with signing on ----------------------------------------------------------------
@pytest.fixture(scope="module")
def signed(ros_domain, tmp_path_factory):
    d = tmp_path_factory.mktemp("auth")
    key = d / "bev_mdo.key"
    key.write_text(KEY + "\n")
    key.chmod(0o600)
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["ros"] = {"timeout_s": 2.0, "retries": 5, "discovery_wait_s": 60.0, "sign_key_file": str(key)}
    path = d / "signed.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    la = Launcher(ros_env(ros_domain), log_dir=d / "logs")
    try:
        for name in BUILTINS:
            la.add(name, discipline_argv(name, str(path)))
        yield {"config": str(path), "launcher": la, "logs": d / "logs"}
    finally:
        la.stop()
    for n in la.nodes:
        assert n.restarts == 0
    for log in (d / "logs").glob("*.log"):
        assert KEY not in log.read_text()


def test_signed_optimisation_equals_in_process(rclpy_context, signed):
    config = load_config(signed["config"])
    res, stats = coordinator_node.run(config, context=rclpy_context)
    ref = run_optimization(config, InProcessEvaluator(resolve_disciplines(config)))
    for k, v in ref.design.items():
        assert res.design[k] == pytest.approx(v, rel=1e-12)
    assert not any(stats["dropped"].get(r) for r in ("unsigned", "forged", "expired", "replayed"))
    assert KEY not in yaml.safe_dump(config)


def test_unsigned_forged_expired_and_replayed_requests_are_dropped_and_counted(rclpy_context, signed):
    node = rclpy.create_node("attacker", context=rclpy_context)
    stats = NodeStatsListener(node)
    try:
        pub = node.create_publisher(EvaluationRequest, request_topic("vehicle_mass"), REQUEST_QOS)
        assert stats.wait(lambda s: pub.get_subscription_count() >= 1 and s.seen("vehicle_mass"), 60)
        base = stats.counts("vehicle_mass")
        good, wrong = Signer(KEY.encode()), Signer(secrets.token_bytes(32))
        sent = {"unsigned": 0, "forged": 0, "expired": 0, "replayed": 0}
        valid = 0
        for i in range(20):
            pub.publish(_request("attacker-run", 1000 + i))
            sent["unsigned"] += 1
            # a signer returns the bytes it signed: they are what is published
            pub.publish(wrong.sign_request(_request("attacker-run", 2000 + i)))
            sent["forged"] += 1
            pub.publish(good.sign_request(_request("attacker-run", 3000 + i, t_ns=time.time_ns() - 120 * 10**9)))
            sent["expired"] += 1
            data = good.sign_request(_request("attacker-run", 4000 + i))
            pub.publish(data)  # the first copy is authentic and answered
            valid += 1
            pub.publish(data)  # the same bytes again: a replay
            sent["replayed"] += 1

        def done(s):
            c = s.counts("vehicle_mass")
            return c["received"] - base["received"] == sum(sent.values()) + valid
        assert stats.wait(done, 30), stats.counts("vehicle_mass")
        c = stats.counts("vehicle_mass")
        for reason, n in sent.items():
            assert c[f"rejected.{reason}"] - base[f"rejected.{reason}"] == n, reason
        assert c["answered"] - base["answered"] == valid
    finally:
        stats.close()
        node.destroy_node()


def test_coordinator_drops_unsigned_forged_expired_and_replayed_results(rclpy_context, signed):
    node = rclpy.create_node("coordinator_probe", context=rclpy_context)
    good, wrong = Signer(KEY.encode()), Signer(secrets.token_bytes(32))
    ev = RosEvaluator(node, run_id="probe", signer=Signer(KEY.encode()))
    try:
        def result(eid, t_ns=None):
            res = EvaluationResult()
            stamp(res.header, t_ns)
            res.run_id, res.evaluation_id, res.discipline = "probe", eid, "vehicle_mass"
            res.header.frame_id = TAG  # the echo of the request's binding
            res.point_ok = [True]
            protocol.to_named_array({"vehicle_mass_kg": np.array([1500.0])}, res.outputs)
            return res

        for eid in (1, 2, 3, 4, 5):
            ev._pending[(eid, "vehicle_mass")] = _Pending(eid, "vehicle_mass", _request("probe", eid), 1, 0)
        ev._on_result(result(1))
        r = result(2)
        wrong.sign_result(r)
        ev._on_result(r)
        r = result(3, t_ns=time.time_ns() - 60 * 10**9)
        good.sign_result(r)
        ev._on_result(r)
        r = result(4)
        good.sign_result(r)
        ev._on_result(r)  # accepted
        ev._pending[(4, "vehicle_mass")] = _Pending(4, "vehicle_mass", _request("probe", 4), 1, 0)
        ev._on_result(r)  # a replay, even though id 4 is outstanding again
        assert dict(ev.dropped) == {"unsigned": 1, "forged": 1, "expired": 1, "replayed": 1}
        assert [a[0] for a in ev.accepted] == [4]
    finally:
        ev.close()
        node.destroy_node()


@pytest.mark.parametrize("key", ["none", "another"])
def test_a_run_without_the_nodes_key_says_so(rclpy_context, signed, tmp_path, key):
    # Trial across two hosts: a coordinator without the nodes' key ended after its wait with "did not answer
    # a probe (request)", and one with another key with "forged declaration", neither saying what to fix.
    raw = yaml.safe_load(open(signed["config"]))
    raw["ros"] = {**raw["ros"], "discovery_wait_s": 3.0}
    if key == "none":
        del raw["ros"]["sign_key_file"]
    else:
        other = tmp_path / "other.key"
        other.write_text(secrets.token_hex(32) + "\n")
        other.chmod(0o600)
        raw["ros"]["sign_key_file"] = str(other)
    with pytest.raises(ValueError) as exc:
        coordinator_node.run(load_config(raw), context=rclpy_context)
    text = str(exc.value)
    if key == "none":
        assert "did not answer a probe" in text and "give this run the same key" in text, text
    else:
        assert "forged declaration (another key: ros.sign_key_file must name the same key" in text, text
