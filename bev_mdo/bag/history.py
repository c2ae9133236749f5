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


def own_run(bag) -> str | None:
    """The run id the recorder of this bag was started for (None for a standalone recording)."""
    return (bag.info.get("run_id") or None) if isinstance(bag, Bag) else own_run(open_bag(bag))


def _in_run(run_id: str, run: str) -> bool:
    return run_id == run or run_id.startswith(run + "-")


def signer_for(bag, key_file: str | None = None):
    """(Signer or None, why not) for verifying the bag's records: the given key file, else the
    ``ros.sign_key_file`` path named in the bag's stored configuration (the key itself is never
    in the bag). (None, "") when the run was not signed."""
    import yaml

    from bev_mdo.ros.auth import AuthError, Signer, read_key

    if not key_file:
        try:
            config = yaml.safe_load(read_config(bag) or "") or {}
        except yaml.YAMLError:
            config = {}
        key_file = ((config.get("ros") or {}) if isinstance(config, dict) else {}).get("sign_key_file") or ""
    if not key_file:
        return None, ""
    try:
        return Signer(read_key(key_file)), ""
    except AuthError as exc:
        return None, f"cannot verify the iteration records: {exc}"


def history(bag, run_id: str | None = None, *, all_runs: bool = False, key_file: str | None = None,
            checks: dict | None = None) -> list[dict]:
    """One dict per recorded iteration of ONE run, in recording order, verified when it was signed.

    The run is `run_id`, else the bag's own (the run its recorder was started for); a standalone
    recording of several runs needs `run_id` (BagError naming them), unless `all_runs`. Records of
    a signed run are verified with its key (see ``signer_for``); unsigned and forged ones are
    dropped. `checks`, if given, receives {"run_id", "dropped": {reason: n}, "other_runs": n,
    "unverified": why-not or ""}.
    """
    bag = bag if isinstance(bag, Bag) else open_bag(bag)
    run = run_id or own_run(bag)
    decoded = list(bag.decoded(_iteration_topics(bag)))
    if run is None and not all_runs:
        runs = sorted({rec.run_id for _, rec in decoded})
        if len(runs) > 1:
            raise BagError(f"{bag.mcap_path}: the bag holds the iterations of {len(runs)} runs {runs}; "
                           "choose one with --run-id")
    signer, why_not = signer_for(bag, key_file)
    info = {"run_id": run, "dropped": {}, "other_runs": 0, "unverified": why_not}
    rows = []
    for msg, rec in decoded:
        if run is not None and not _in_run(rec.run_id, run):
            info["other_runs"] += 1
            continue
        if signer is not None:
            why = signer.verify_iteration(msg.data)  # the recorded bytes, as they were sent
            if why is not None:
                info["dropped"][why] = info["dropped"].get(why, 0) + 1
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
    if checks is not None:
        checks.update(info)
    return rows


def check_note(checks: dict) -> str:
    """One line about what history() left out or could not verify ('' if nothing)."""
    parts = []
    if checks.get("dropped"):
        parts.append("dropped " + ", ".join(f"{n} {k}" for k, n in sorted(checks["dropped"].items()))
                     + " iteration record(s)")
    if checks.get("other_runs"):
        parts.append(f"skipped {checks['other_runs']} record(s) of other runs")
    if checks.get("unverified"):
        parts.append(checks["unverified"])
    return "; ".join(parts)


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


def last_iterate(bag, run_id: str | None = None, key_file: str | None = None,
                 checks: dict | None = None) -> tuple[str, dict[str, float], int]:
    """(config_yaml, design of the last verified iteration of the bag's own run, its iteration
    number), for resume. BagError when the run was signed but its records cannot be verified."""
    bag = bag if isinstance(bag, Bag) else open_bag(bag)
    checks = {} if checks is None else checks
    rows = history(bag, run_id, key_file=key_file, checks=checks)
    if checks.get("unverified"):
        raise BagError(f"{bag.mcap_path}: {checks['unverified']}; will not resume from unverified records "
                       "(give the key with --key-file)")
    if not rows:
        raise BagError(f"{bag.mcap_path}: no IterationRecord on {ITERATION_TOPIC}; nothing to resume")
    last = rows[-1]
    return read_config(bag), dict(last["design"]), int(last["iteration"])


def records_phrase(rows: list[dict]) -> str:
    """'4 records (iterations 0-3)': a count of records, not of iterations; record 0 is the start, so a
    run that ``optimize`` reports with 'iterations 3' has 4 records (saying '4 iterations' contradicted it)."""
    first, last = rows[0].get("iteration"), rows[-1].get("iteration")
    span = f" (iterations {first}-{last})" if first is not None and last is not None else ""
    return f"{len(rows)} record{'s' if len(rows) != 1 else ''}{span}"
