"""Optimisation history from the IterationRecord messages of a bag (no ROS needed)."""
from __future__ import annotations

import csv
import io

from bev_mdo.bag.errors import BagError
from bev_mdo.bag.reader import Bag, open_bag, read_config

ITERATION_TOPIC = "/bev_mdo/iteration"
ITERATION_TYPE = "bev_mdo_msgs/msg/IterationRecord"


def named(block, point: int = 0) -> dict[str, float]:
    """One point of a decoded NamedArray (column-major) as {name: value}."""
    n = int(block.batch_size) or 1
    values = list(block.values)
    return {name: float(values[j * n + point]) for j, name in enumerate(block.names)
            if j * n + point < len(values)}


def _iteration_topics(bag: Bag) -> list[str]:
    topics = [t for t, ty in bag.topics.items() if ty == ITERATION_TYPE]
    return sorted(topics, key=lambda t: t != ITERATION_TOPIC)


def history(bag, run_id: str | None = None) -> list[dict]:
    """One dict per recorded iteration, in recording order."""
    bag = bag if isinstance(bag, Bag) else open_bag(bag)
    rows = []
    for msg, rec in bag.decoded(_iteration_topics(bag)):
        if run_id is not None and rec.run_id != run_id:
            continue
        rows.append({
            "run_id": rec.run_id,
            "iteration": int(rec.iteration),
            "sequence": int(rec.sequence),
            "formulation": rec.formulation,
            "optimizer": rec.optimizer,
            "design": named(rec.design),
            "objective_name": rec.objective_name,
            "objective": float(rec.objective),
            "constraints": named(rec.constraints),
            "max_violation": float(rec.max_violation),
            "feasible": bool(rec.feasible),
            "mda_evaluations": int(rec.mda_evaluations),
            "discipline_evaluations": {n: int(c) for n, c in
                                       zip(rec.discipline_names, rec.discipline_evaluations)},
            "wall_time_s": float(rec.wall_time_s),
            "log_time_ns": msg.log_time_ns,
        })
    return rows


def flat_rows(rows: list[dict]) -> list[dict]:
    """Flatten nested design/constraints/evaluation counts into prefixed columns."""
    flat = []
    for row in rows:
        out = {k: v for k, v in row.items()
               if k not in ("design", "constraints", "discipline_evaluations", "log_time_ns")}
        out.update({f"design.{k}": v for k, v in row["design"].items()})
        out.update({f"constraint.{k}": v for k, v in row["constraints"].items()})
        out.update({f"evaluations.{k}": v for k, v in row["discipline_evaluations"].items()})
        flat.append(out)
    return flat


def to_csv(rows: list[dict]) -> str:
    """CSV text of the flattened history (columns: union over all rows, first-seen order)."""
    flat = flat_rows(rows)
    columns: list[str] = []
    for row in flat:
        columns += [k for k in row if k not in columns]
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    writer.writerows(flat)
    return buf.getvalue()


def last_iterate(bag) -> tuple[str, dict[str, float], int]:
    """(config_yaml, design of the last recorded iteration, its iteration number), for resume."""
    bag = bag if isinstance(bag, Bag) else open_bag(bag)
    rows = history(bag)
    if not rows:
        raise BagError(f"{bag.mcap_path}: no IterationRecord on {ITERATION_TOPIC}; nothing to resume")
    last = rows[-1]
    return read_config(bag), dict(last["design"]), int(last["iteration"])
