"""Shared helpers for the bag tests: deterministic synthetic bev_mdo traffic."""
from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
VENV = ROOT / ".venv"
DISCIPLINES = ("vehicle_mass", "energy")
DESIGN = ("motor_kw", "gear_ratio", "battery_kwh")
CONFIG_YAML = "problem:\n  objective: powertrain_cost_usd\n  design:\n    motor_kw: [50, 200]\n"
T0_NS = 1_700_000_000_000_000_000


os.environ.setdefault("AMENT_PREFIX_PATH", str(VENV))


def design_of(i: int) -> dict[str, float]:
    return {"motor_kw": 80.0 + i, "gear_ratio": 9.0 - 0.1 * i, "battery_kwh": 60.0 + 0.5 * i}


def synthetic(n_iterations: int = 20):
    """[(topic, type_name, message)] for n iterations: requests, results, iteration records."""
    from bev_mdo_msgs.msg import (EvaluationRequest, EvaluationResult, IterationRecord,
                                  NamedArray)

    out = []
    seq = 0
    for i in range(n_iterations):
        d = design_of(i)
        for k, disc in enumerate(DISCIPLINES):
            eid = i * len(DISCIPLINES) + k
            stamp = T0_NS + eid * 1_000_000
            req = EvaluationRequest(run_id="run-1", evaluation_id=eid, sequence=seq, iteration=i,
                                    discipline=disc)
            req.header.stamp.sec, req.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
            req.inputs = NamedArray(names=list(DESIGN), batch_size=1, values=[d[n] for n in DESIGN])
            out.append((f"/bev_mdo/{disc}/request", "bev_mdo_msgs/msg/EvaluationRequest", req))
            res = EvaluationResult(run_id="run-1", evaluation_id=eid, sequence=seq,
                                   discipline=disc, instance=f"{disc}_node", status=0,
                                   point_ok=[True], compute_time_s=1e-4 * (k + 1) + 1e-6 * i)
            rstamp = stamp + 250_000
            res.header.stamp.sec, res.header.stamp.nanosec = divmod(rstamp, 1_000_000_000)
            res.outputs = NamedArray(names=[f"{disc}_out_kg"], batch_size=1, values=[1000.0 + i + k])
            out.append(("/bev_mdo/result", "bev_mdo_msgs/msg/EvaluationResult", res))
            seq += 1
        rec = IterationRecord(run_id="run-1", sequence=i, iteration=i, formulation="mdf",
                              optimizer="SLSQP", objective_name="powertrain_cost_usd",
                              objective=10000.0 - 10.0 * i, max_violation=max(0.0, 5.0 - i),
                              feasible=i >= 5, mda_evaluations=i + 1,
                              discipline_names=list(DISCIPLINES),
                              discipline_evaluations=[i + 1, i + 1], wall_time_s=0.01 * i)
        rec.design = NamedArray(names=list(DESIGN), batch_size=1, values=[d[n] for n in DESIGN])
        rec.constraints = NamedArray(names=["range_km"], batch_size=1, values=[300.0 + i])
        out.append(("/bev_mdo/iteration", "bev_mdo_msgs/msg/IterationRecord", rec))
    return out


def write_synthetic(bag_dir: Path, n_iterations: int = 20, chunk_size_bytes: int = 2048):
    """Write the synthetic traffic to a bag; returns the [(topic, type, msg)] written."""
    from rclpy.serialization import serialize_message

    from bev_mdo.bag.writer import BagWriter

    msgs = synthetic(n_iterations)
    with BagWriter(bag_dir, metadata={"config_yaml": CONFIG_YAML, "run_id": "run-1"},
                   chunk_size_bytes=chunk_size_bytes) as writer:
        for j, (topic, type_name, msg) in enumerate(msgs):
            writer.add_topic(topic, type_name)
            writer.write(topic, serialize_message(msg), T0_NS + j * 1000, T0_NS + j * 1000 - 7)
    return msgs


@pytest.fixture
def synthetic_bag(tmp_path):
    bag_dir = tmp_path / "run1"
    msgs = write_synthetic(bag_dir)
    return bag_dir, msgs


def cli(*argv: str) -> tuple[int, str, str]:
    """Run ``bev-mdo`` in-process; returns (exit code, stdout, stderr)."""
    import contextlib
    import io

    from bev_mdo.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(list(argv))
    return code, out.getvalue(), err.getvalue()


sys.path.insert(0, str(Path(__file__).parent))
