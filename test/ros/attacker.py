"""An attacker on a run's domain: ``python attacker.py CONFIG`` forges, for the run of CONFIG (see
test_trust.py), declarations of its ``energy`` discipline, energy results for every data-flow request it
overhears and iteration records under the run's id and another one. It prints ``ready`` once its
publishers and reader exist, spins until its stdin is closed, then prints one JSON line: what it sent
and the run ids it saw.

It runs as a process of its own, started afresh for each attempt: a participant in the long-lived test
process once missed every run of a module (its discovery stalled), and a fresh one does not carry that over."""
from __future__ import annotations

import json
import sys
import threading

import numpy as np
import rclpy
from rclpy.executors import ExternalShutdownException

from bev_mdo import binding, protocol
from bev_mdo.config import load_config, resolve_disciplines
from bev_mdo.ros.common import (INFO_QOS, INFO_TOPIC, ITERATION_QOS, ITERATION_TOPIC, MDA_REQUEST_TOPIC,
                                MDA_RESULT_QOS, REQUEST_QOS, RESULT_QOS, RESULT_TOPIC, mda_result_topic, stamp)
from bev_mdo_msgs.msg import DisciplineInfo, EvaluationRequest, EvaluationResult, IterationRecord

FORGED_DESIGN = {"motor_kw": 120.0, "gear_ratio": 1.0, "battery_kwh": 30.0}


class Attacker:
    """Forges declarations, results and iteration records; counts what it sent."""

    def __init__(self, config):
        self.node = rclpy.create_node("attacker")
        self.sent = {"results": 0, "records": 0, "other_run_records": 0}
        self.run_ids: set[str] = set()
        self._info = self.node.create_publisher(DisciplineInfo, INFO_TOPIC, INFO_QOS)
        self._res = self.node.create_publisher(EvaluationResult, RESULT_TOPIC, RESULT_QOS)
        self._mda = self.node.create_publisher(EvaluationResult, mda_result_topic("energy"), MDA_RESULT_QOS)
        self._iter = self.node.create_publisher(IterationRecord, ITERATION_TOPIC, ITERATION_QOS)
        self._sub = self.node.create_subscription(EvaluationRequest, MDA_REQUEST_TOPIC, self._on_request,
                                                  REQUEST_QOS, raw=True)
        fp, effective = binding.fingerprint(config, "energy")
        energy = [d for d in resolve_disciplines(config) if d.name == "energy"][0]
        for k, sig in enumerate(("", "0" * 64)):  # unsigned, then with a made-up signature
            info = DisciplineInfo()
            stamp(info.header)
            info.discipline, info.instance = "energy", f"energy_node_attacker{k}"
            info.inputs, info.outputs = list(energy.inputs), list(energy.outputs)
            info.fingerprint, info.effective_config, info.signature = fp, effective, sig
            self._info.publish(info)

    def _on_request(self, data) -> None:
        req = protocol.decode_request(data)
        if "energy" not in req.flow or not req.run_id or req.run_id.endswith("-baseline"):
            return
        self.run_ids.add(req.run_id)
        n = int(req.inputs.batch_size)
        out = protocol.result()
        stamp(out.header)
        out.header.frame_id = req.header.frame_id
        out.run_id, out.evaluation_id, out.discipline, out.instance = req.run_id, req.evaluation_id, "energy", "x"
        out.point_ok = np.ones(n, bool)
        out.outputs = protocol.batch({"energy_wh_per_km": np.full(n, 80.0), **protocol.from_named_array(req.inputs)})
        out.flow = list(req.flow)
        data_out = protocol.encode_result(out)
        self._mda.publish(data_out)
        self._res.publish(data_out)
        self.sent["results"] += 1
        if self.sent["records"] < 40:
            for run_id, key in ((req.run_id, "records"), ("someone-else", "other_run_records")):
                rec = IterationRecord()
                stamp(rec.header)
                rec.run_id, rec.iteration, rec.objective_name, rec.objective = run_id, 999, "energy_wh_per_km", 80.0
                protocol.to_named_array({k: np.array([v]) for k, v in FORGED_DESIGN.items()}, rec.design)
                rec.feasible = True
                rec.signature = "0" * 64 if self.sent[key] % 2 else ""
                self._iter.publish(rec)
                self.sent[key] += 1


def main() -> int:
    rclpy.init()
    attacker = Attacker(load_config(sys.argv[1]))
    print("ready", flush=True)
    threading.Thread(target=lambda: (sys.stdin.read(), rclpy.try_shutdown()), daemon=True).start()
    try:
        rclpy.spin(attacker.node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    print(json.dumps({"sent": attacker.sent, "run_ids": sorted(attacker.run_ids)}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
