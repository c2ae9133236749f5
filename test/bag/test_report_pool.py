"""`report` shows the work of every instance of a pooled discipline, read from the bag alone:
the results each instance answered, its points and throughput, and the shares addressed to it that it
never answered (re-sent to another instance)."""
from __future__ import annotations

import numpy as np

from .conftest import CONFIG_YAML, T0_NS, cli


def _pool_traffic():
    from bev_mdo_msgs.msg import EvaluationRequest, EvaluationResult, NamedArray

    out = []
    t = [T0_NS]

    def stamp(h):
        t[0] += 1_000_000
        h.stamp.sec, h.stamp.nanosec = divmod(t[0], 1_000_000_000)

    def request(eid, disc, n, tag, flow=()):
        req = EvaluationRequest(run_id="run-1", evaluation_id=eid, discipline=disc, flow=list(flow))
        stamp(req.header)
        req.header.frame_id = tag
        req.inputs = NamedArray(names=["motor_kw"], batch_size=n, values=list(np.linspace(50, 90, n)))
        topic = "/bev_mdo/mda_request" if flow else f"/bev_mdo/{disc}/request"
        out.append((topic, "bev_mdo_msgs/msg/EvaluationRequest", req))

    def result(eid, disc, inst, n, compute_s, ok=None):
        res = EvaluationResult(run_id="run-1", evaluation_id=eid, discipline=disc, instance=inst, status=0,
                               point_ok=list(ok if ok is not None else [True] * n), compute_time_s=compute_s)
        stamp(res.header)
        res.outputs = NamedArray(names=["energy_wh_per_km"], batch_size=n, values=[100.0] * n)
        out.append(("/bev_mdo/result", "bev_mdo_msgs/msg/EvaluationResult", res))

    # warm-up: an empty request to any instance, answered by both (not counted)
    request(1, "energy", 0, "fp:energy=aa")
    result(1, "energy", "/energy_node", 0, 0.0)
    result(1, "energy", "/energy_node_e1", 0, 0.0)
    # a batch of 10 shared 6 + 4
    request(2, "energy", 6, "fp:energy=aa@energy_node")
    request(3, "energy", 4, "fp:energy=aa@energy_node_e1")
    result(2, "energy", "/energy_node", 6, 0.06)
    result(3, "energy", "/energy_node_e1", 4, 0.02, ok=[True, False, True, True])
    # the next batch: e1 stalls on its share of 5, which goes to the other instance
    request(4, "energy", 5, "fp:energy=aa@energy_node")
    request(5, "energy", 5, "fp:energy=aa@energy_node_e1")
    result(4, "energy", "/energy_node", 5, 0.05)
    request(6, "energy", 5, "fp:energy=aa@energy_node")
    result(6, "energy", "/energy_node", 5, 0.05)
    # a data-flow share: one request, energy addressed to e1, vehicle_mass to any (one instance)
    request(7, "", 2, "fp:vehicle_mass=bb,energy=aa@energy_node_e1", flow=("vehicle_mass", "energy"))
    result(7, "vehicle_mass", "/vehicle_mass_node", 2, 0.001)
    result(7, "energy", "/energy_node_e1", 2, 0.01)
    return out


def _write(bag_dir):
    from rclpy.serialization import serialize_message

    from bev_mdo.bag.writer import BagWriter

    with BagWriter(bag_dir, metadata={"config_yaml": CONFIG_YAML, "run_id": "run-1"}) as writer:
        for j, (topic, type_name, msg) in enumerate(_pool_traffic()):
            writer.add_topic(topic, type_name)
            writer.write(topic, serialize_message(msg), T0_NS + j * 1000, T0_NS + j * 1000 - 7)


def test_instance_work_from_the_bag(tmp_path):
    from bev_mdo.bag.reader import open_bag
    from bev_mdo.bag.report import instance_work

    _write(tmp_path / "pool")
    work = instance_work(open_bag(tmp_path / "pool"))
    e0, e1 = work["energy"]["energy_node"], work["energy"]["energy_node_e1"]
    assert (e0["results"], e0["points"], e0["unanswered_shares"]) == (3, 16, 0)
    assert e0["compute_s"] == 0.16 and e0["points_per_compute_s"] == 100.0
    assert (e1["results"], e1["points"], e1["failed_points"]) == (2, 6, 1)
    assert (e1["unanswered_shares"], e1["unanswered_points"]) == (1, 5)  # the stalled share
    assert e1["points_per_compute_s"] == 200.0
    assert list(work["vehicle_mass"]) == ["vehicle_mass_node"]


def test_report_shows_the_work_per_instance(tmp_path):
    _write(tmp_path / "pool")
    code, _, err = cli("report", str(tmp_path / "pool"))
    assert code == 0, err
    md = (tmp_path / "pool" / "report.md").read_text()
    assert "## Work per instance (worker pools)" in md
    assert "| energy | energy_node | 3 | 16 | 72.7 % | 0.160 | 100.0 | 0 | 0 (0) |" in md
    assert "| energy | energy_node_e1 | 2 | 6 | 27.3 % | 0.030 | 200.0 | 1 | 1 (5) |" in md
    assert "| vehicle_mass |" not in md.split("## Work per instance")[1].split("Unanswered")[0]  # one instance
