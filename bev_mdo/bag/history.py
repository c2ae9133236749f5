"""Optimisation history from the IterationRecord messages of a bag (no ROS needed)."""
from __future__ import annotations

import csv
import io
import json
import math

from bev_mdo.bag.errors import BagError
from bev_mdo.bag.reader import Bag, open_bag
from bev_mdo.bag.order import RecordOrder, Sequence, in_run, stamp_ns  # noqa: F401 - RecordOrder: read from here
from bev_mdo.bag.signing import verifier
from bev_mdo.protocol import parse_start_tag

ITERATION_TOPIC = "/bev_mdo/iteration"
ITERATION_TYPE = "bev_mdo_msgs/msg/IterationRecord"
ANSWERS_METADATA = "bev_mdo_answers"  # MCAP metadata record of an in-process run's bag
ANSWERS_FILE = "answers.json"         # beside the recorder node's bag over ROS


def named(block) -> dict[str, float]:
    """The first point of a decoded NamedArray (column-major) as {name: value}."""
    n = int(block.batch_size) or 1
    values = list(block.values)
    return {name: float(values[j * n]) for j, name in enumerate(block.names) if j * n < len(values)}


def history(bag, run_id: str | None = None, *, all_runs: bool = False, key_file: str | None = None,
            checks: dict | None = None, no_verify: bool = False) -> list[dict]:
    """One dict per recorded iteration of ONE run, in recording order, verified when it was signed.

    The run is `run_id`, else the bag's own (the run its recorder was started for); a standalone
    recording of several runs needs `run_id` (BagError naming them), unless `all_runs`. Records of
    a signed run are verified with its key (see ``bag.signing``; BagError when the bag's signing record
    and stored config disagree); unsigned and forged ones are dropped, and so are records seen before
    (``Sequence``); one recorded after a later record of its run is put back in its place (``late``).
    `no_verify` reads without checking signatures (the note says so).
    `checks`, if given, receives {"run_id", "dropped": {reason: n}, "missing": n, "late": n, "other_runs": n,
    "other_run_ids": [the runs of those records], "unverified": note or ""} and, for a sweep's bag cut
    short, "unfinished": note.
    """
    return verified_history(bag, run_id, all_runs=all_runs, key_file=key_file, checks=checks, no_verify=no_verify)[0]


def verified_history(bag, run_id: str | None = None, *, all_runs: bool = False, key_file: str | None = None,
                     checks: dict | None = None, no_verify: bool = False) -> tuple[list[dict], object]:
    """(``history``, the Signer its records were verified with or None), for a reader that checks what else
    the bag stores (its answers: ``read_answers``) with the same key."""
    bag = bag if isinstance(bag, Bag) else open_bag(bag)
    run = run_id or bag.info.get("run_id") or None  # the run the bag's recorder was started for, if any
    decoded = list(bag.decoded([t for t, ty in bag.topics.items() if ty == ITERATION_TYPE]))
    if run is None and not all_runs:
        runs = sorted({rec.run_id for _, rec in decoded})
        if len(runs) > 1:
            raise BagError(f"{bag.mcap_path}: the bag holds the iterations of {len(runs)} runs {runs}; "
                           "choose one with --run-id")
    stored = bag.stored_config
    check = verifier(bag, key_file, no_verify)
    signer = check.signer
    info = {"run_id": run, "dropped": {}, "missing": 0, "other_runs": 0, "other_run_ids": [],
            "unverified": check.note}
    order = Sequence(stored.window_s)
    rows = []
    for msg, rec in decoded:
        if run is not None and not in_run(rec.run_id, run):
            info["other_runs"] += 1
            if rec.run_id not in info["other_run_ids"]:
                info["other_run_ids"].append(rec.run_id)
            continue
        if signer is None and rec.signature and not no_verify:  # signed records in a bag that says it was not signed
            why = ("it holds no config (a recorder started without one)" if not stored.text.strip()
                   else "was its config edited?")
            raise BagError(f"{bag.mcap_path}: its records are signed but the bag names no key to verify them "
                           f"and none was given or found beside it ({why}); give the key with --key-file, or "
                           "--no-verify")
        # dropped: a record that does not verify (the recorded bytes, as they were sent), then one out of order
        why = ((signer.verify_iteration(msg.data) if signer is not None else None)
               or order.check(rec.run_id, int(rec.sequence), stamp_ns(rec.header), msg.log_time_ns))
        if why is not None:
            info["dropped"][why] = info["dropped"].get(why, 0) + 1
            continue
        values = named(rec.design)
        start = parse_start_tag(rec.header.frame_id)
        row = {
            "run_id": rec.run_id,
            "iteration": int(rec.iteration),
            **({"start": start[0] + 1, "starts": start[1], "seed": start[2]} if start else {}),
            "sequence": int(rec.sequence),
            "formulation": rec.formulation,
            "optimizer": rec.optimizer,
            "design": {k: v for k, v in values.items() if stored.is_design(k)},
            **({"couplings": {k: v for k, v in values.items() if not stored.is_design(k)}}
               if rec.formulation == "idf" else {}),
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
        }
        rows.append(row)
    if order.late:  # records recorded after a later record of their run: each run's, in its places, in sequence order
        places: dict[str, list[int]] = {}
        for i, r in enumerate(rows):
            places.setdefault(r["run_id"], []).append(i)
        for at in places.values():
            for i, r in zip(at, sorted((rows[i] for i in at), key=lambda r: r["sequence"])):
                rows[i] = r
    info["missing"], info["late"] = order.missing, order.late
    planned = int(bag.info.get("designs") or 0)  # a sweep's bag names its count of designs
    if rows and rows[-1]["formulation"] == "doe" and len(rows) < planned:
        info["unfinished"] = f"the sweep's bag holds {len(rows)} of its {planned} designs (it was stopped while written)"
    if rows and (run_id is None or run_id == bag.info.get("run_id")):  # the bag's own run: its end-of-run record
        tail = missing_tail(rows, read_answers(bag, signer))               # counts what it should hold
        if tail:
            info["tail"] = f"{tail}; the run's result is in its end-of-run record (report and resume take it from there)"
    if checks is not None:
        checks.update(info)
    return rows, signer


def check_note(checks: dict) -> str:
    """One line about what history() left out or could not verify ('' if nothing)."""
    parts = []
    if checks.get("dropped"):
        parts.append("dropped " + ", ".join(f"{n} {k}" for k, n in sorted(checks["dropped"].items()))
                     + " iteration record(s)")
    if checks.get("missing"):
        parts.append(f"{checks['missing']} iteration record(s) missing (gaps in the run's sequence numbers)")
    if checks.get("late"):
        parts.append(f"{checks['late']} iteration record(s) recorded after a later one (read in sequence order)")
    if checks.get("other_runs"):
        parts.append(f"skipped {checks['other_runs']} record(s) of other runs")
    if checks.get("unverified"):
        parts.append(checks["unverified"])
    if checks.get("unfinished"):
        parts.append(checks["unfinished"])
    if checks.get("tail"):
        parts.append(checks["tail"])
    if checks.get("answers"):
        parts.append(checks["answers"])
    if checks.get("config"):  # bag/report: the stored config does not load here
        parts.append(checks["config"])
    return "; ".join(parts)


def status(row: dict) -> str:
    """"ok", or "failed" when the record's point has no value: its objective or a constraint is NaN (a
    discipline raised or gave a non-finite output; the record keeps no reason)."""
    values = [row["objective"], *row["constraints"].values()]
    return "ok" if all(math.isfinite(v) for v in values) else "failed"


def flat_rows(rows: list[dict]) -> list[dict]:
    """Flatten nested design/constraints/evaluation counts into prefixed columns; ``status`` after
    ``feasible``."""
    flat = []
    for row in rows:
        out = {}
        for k, v in row.items():
            if k not in ("design", "couplings", "constraints", "discipline_evaluations", "log_time_ns"):
                out[k] = v
            if k == "feasible":
                out["status"] = status(row)
        out.update({f"design.{k}": v for k, v in row["design"].items()})
        out.update({f"coupling.{k}": v for k, v in row.get("couplings", {}).items()})
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


def read_answers(bag: Bag, signer=None, checks: dict | None = None) -> dict | None:
    """The end-of-run answers stored with a bag (metadata record or answers.json), or None. A signed run's
    (``signer``: its records' Verifier.signer) count only when signed with its key: they name the run's
    result, which resume goes on from and report describes. Others are left out (None) and `checks` gets
    "answers": why."""
    rec = bag.metadata.get(ANSWERS_METADATA)
    if rec and "answers_json" in rec:
        text, sig = rec["answers_json"], rec.get("answers_signature", "")
    else:
        path = bag.bag_dir / ANSWERS_FILE
        if not path.is_file():
            return None
        text = path.read_text(encoding="utf-8")
        sig_file = path.with_name(ANSWERS_FILE + ".sig")
        sig = sig_file.read_text(encoding="utf-8").strip() if sig_file.is_file() else ""
    why = signer.verify_answers(text, sig) if signer is not None else None
    if why is not None:
        if checks is not None:
            checks["answers"] = (f"its stored end-of-run answers are {why} (not signed with the run's key), so they are "
                                 "left out: the run's result is not taken from them")
        return None
    return json.loads(text)


def run_ending(bag: Bag, rows: list[dict], answers: dict | None, checks: dict | None = None,
               then: str = "what follows is") -> tuple[bool, str] | None:
    """(finished, one line) on how the bag's optimisation ended, from its end-of-run record (``read_answers``: stored
    by api/runbag.finish when the run ends, with the disciplines that stopped answering); None for a sweep. finished
    is None where that is not known (the record left out, or nothing in the bag shows the run it tells of). ``then``
    leads the words on the last record of a run that did not finish (report: the iterate shown after the line)."""
    if rows and rows[-1].get("formulation") == "doe":
        return None
    if answers is None:
        if (checks or {}).get("answers"):
            return None, "how the run ended is not known: its end-of-run record is left out (not signed with its key)"
        last = rows[-1] if rows else {}
        whose = (f"; {then} the last recorded iterate of its start {last['start']} of {last['starts']} (resume goes "
                 "on from each start's own last record), not a result" if last.get("starts") else
                 f"; {then} its last recorded iterate, not a result" if rows else ", and no iteration record either")
        if by_optimize(bag):
            return False, ("**the run did not finish**: the bag holds no end-of-run record (a signal, SIGINT or "
                           f"SIGTERM, or an error stopped it){whose}")
        return None, ("**no end-of-run record**: the run did not finish, or its coordinator was started by hand "
                      "(coordinator_node stores none), or the bag was recorded apart from it (`bev-mdo record`) or "
                      f"copied without its {ANSWERS_FILE}{whose.replace(', not a result', '')}")
    lost = answers.get("unresponsive_disciplines")
    if lost:
        why = answers.get("stopped") or f"{', '.join(lost)} stopped answering"
        return True, (f"**the run ended early (exit status 4)**: {why}; its result is the best point evaluated before "
                      "that, not an optimum")
    if not rows:  # a bag cut short before its first record: only the record (answers.json beside it) tells of the run
        n = answers.get("records")
        held = f"none of the run's {n} iteration records" if n else "no iteration record"
        where = "stored in the bag" if ANSWERS_METADATA in bag.metadata else f"{ANSWERS_FILE} beside the bag"
        return None, (f"how the run ended is not known from the bag: **it holds {held}**; its end-of-run record "
                      f"({where}) says the run finished")
    if tail := missing_tail(rows, answers):
        return True, (f"the run finished, but **{tail}**; the result and the answers below are its end-of-run "
                      "record's")
    return True, "the run finished: the bag holds its end-of-run record (its result and the answers below)"


def by_optimize(bag: Bag) -> bool:
    """Whether `bag` was written by ``bev-mdo optimize`` (which stores an end-of-run record when the run ends), not
    by a recorder and coordinator started by hand: in process, or over ROS with the run's logs/ beside it."""
    return bag.info.get("transport") == "inprocess" or (bag.bag_dir / "logs").is_dir()


STOPPED = "its recorder stopped before the run ended, or records were removed from the bag"  # what a short bag tells


def missing_tail(rows: list[dict], answers: dict | None) -> str:
    """'' or how the bag's iteration records end before the run did: its end-of-run record (api/runbag.finish)
    counts records past the bag's last (a recorder that died during the run), or, stored before it counted
    them, names a result no record holds."""
    if not rows or not answers or rows[-1].get("formulation") == "doe":
        return ""
    last, end = rows[-1]["iteration"], answers.get("last_iteration")
    if end is not None and end > last:
        return (f"the bag's iteration records stop at iteration {last} of the run's {end} ({end - last} missing at the "
                f"end: {STOPPED})")
    result = answers.get("result_design")
    if end is None and result and not any(r["design"] == result for r in rows):
        return (f"the bag's iteration records stop at iteration {last}, before the run's result (no record holds the "
                f"design its end-of-run record names: {STOPPED})")
    return ""


def answered_result(rows: list[dict], answers: dict | None) -> dict | None:
    """The run's result as its end-of-run record names it, as a history row marked ``from_answers``, when the
    bag's records end before the run's result (``missing_tail``; an earlier record at its design is not it);
    else None. Its iteration, objective and violation are None where the record predates them (``report``
    analyses the design again for the objective)."""
    result = (answers or {}).get("result_design")
    if not result or not missing_tail(rows, answers):
        return None
    at = answers.get("result_iteration")
    if (at <= rows[-1]["iteration"]) if at is not None else any(r["design"] == result for r in rows):
        return None  # the bag holds the result's record
    last = rows[-1]
    return {**{k: last[k] for k in ("run_id", "formulation", "optimizer", "objective_name")},
            "iteration": answers.get("result_iteration"), "design": dict(result),
            "objective": answers.get("result_objective"), "constraints": {},
            "max_violation": answers.get("result_max_violation"),
            "feasible": bool(answers.get("result_feasible", answers.get("feasible"))),
            "mda_evaluations": answers.get("mda_evaluations"), "from_answers": True}


def mda_total(rows: list[dict], answers: dict | None = None) -> str:
    """"N multidisciplinary evaluations": the run's total as its end-of-run record counts it, else summed over
    the starts of a multi-start (each start counts its own: the last record of each), else the last record's."""
    if (answers or {}).get("mda_evaluations") is not None:
        return f"{answers['mda_evaluations']} multidisciplinary evaluations (the run's total)"
    if rows[-1].get("formulation") == "doe":  # a sweep's: its designs
        return f"{rows[-1]['mda_evaluations']} multidisciplinary evaluations"
    if not rows[-1].get("starts"):
        return f"{rows[-1]['mda_evaluations']} multidisciplinary evaluations (to the last record)"
    last: dict = {}
    for r in rows:
        last[r.get("start")] = max(last.get(r.get("start"), 0), r["mda_evaluations"])
    return f"{sum(last.values())} multidisciplinary evaluations (to the last record of each of its {len(last)} starts)"


def headline(rows: list[dict], sign: float = 1.0, answers: dict | None = None) -> int:
    """The record that stands for the run: a finished optimisation's result (the last feasible record at
    the ``result_design`` its stored ``answers`` name: with ``--starts``, or an earlier best point, it is
    not the last record), else its last iterate; a sweep's (formulation ``doe``, its records in no order)
    best design: the best feasible objective, else the least violated (a failed design, violation nan,
    last). ``sign``: +1 minimise, -1 maximise."""
    result = (answers or {}).get("result_design")
    at = [i for i, r in enumerate(rows) if result and r["feasible"] and r["design"] == result]
    if at:  # a run stopped by a discipline that stopped answering: where its result was found (mdo.driver)
        return at[0] if (answers or {}).get("unresponsive_disciplines") else at[-1]
    if not rows or rows[-1].get("formulation") != "doe":
        return len(rows) - 1

    def rank(i):
        r = rows[i]
        v = r["max_violation"] if r["max_violation"] == r["max_violation"] else float("inf")
        return (0, sign * r["objective"]) if r["feasible"] else (1, v)
    return min(range(len(rows)), key=rank)


def last_iterate(bag, run_id: str | None = None, key_file: str | None = None,
                 checks: dict | None = None, no_verify: bool = False) -> tuple[str, dict | list, int]:
    """(config_yaml, design (IDF: and couplings) of the last verified iteration of the bag's own run, or of a sweep's best
    design (``headline``; `checks` then gets "sweep": ``sweep_phrase``), its iteration number), for
    resume; for an interrupted multi-start, a list of each start's design (``each_start``) in its place.
    BagError when the run was signed but its records cannot be verified."""
    bag = bag if isinstance(bag, Bag) else open_bag(bag)
    checks = {} if checks is None else checks
    rows, signer = verified_history(bag, run_id, key_file=key_file, checks=checks, no_verify=no_verify)
    if not rows and checks["other_run_ids"]:
        own = "" if run_id else " (the bag's own)"
        raise BagError(f"{bag.mcap_path}: no record of run {checks['run_id']}{own}; "
                       f"{runs_held(checks['other_run_ids'])}; choose one with --run-id")
    if not rows:
        raise BagError(f"{bag.mcap_path}: no IterationRecord on {ITERATION_TOPIC}; nothing to resume")
    answers = read_answers(bag, signer, checks)
    told = answered_result(rows, answers)  # the bag lost the records after the result: the record's word
    k = headline(rows, -1.0 if bag.stored_config.maximized else 1.0, answers)
    row = told or rows[k]
    if told is not None:
        at = f"iteration {told['iteration']}, " if told["iteration"] is not None else ""
        checks["result"] = (f"the run's result ({at}from its end-of-run record: the bag's iteration records stop at "
                            f"iteration {rows[-1]['iteration']})")
    elif k != len(rows) - 1 and row["formulation"] != "doe":
        checks["result"] = f"the run's result (iteration {row['iteration']}, not its last record)"
    if checks is not None and row["formulation"] == "doe":
        checks["sweep"] = sweep_phrase(row, len(rows))
    if row.get("starts") and not (answers or {}).get("result_design"):  # an interrupted multi-start
        return bag.stored_config.text, each_start(rows, row, checks), int(row["iteration"])
    return (bag.stored_config.text, {**row["design"], **row.get("couplings", {})},
            int(rows[-1]["iteration"] if row["iteration"] is None else row["iteration"]))


def each_start(rows: list[dict], last: dict, checks: dict) -> list[dict | None]:
    """The design (IDF: and couplings) of each start's last record of an interrupted multi-start whose
    last record is `last`, in start order; None for a start with no record (`checks` gets "starts":
    what the resume goes on from, and "seed": the sample's, to draw such a start's point again)."""
    n = last["starts"]
    final: dict[int, dict] = {}
    for r in rows:
        if r.get("starts") == n and r.get("seed") == last.get("seed"):
            final[r["start"]] = r
    checks["seed"] = last.get("seed")
    if n <= 10:
        checks["starts"] = (f"the last record of each of its {n} starts (iterations "
                            + ", ".join(str(final[i]["iteration"]) if i in final else "none"
                                        for i in range(1, n + 1)) + ")")
    else:  # 800 starts: counts and a few of each, not 800 numbers on one line
        have = [i for i in range(1, n + 1) if i in final]
        none = [i for i in range(1, n + 1) if i not in final]
        at = [f"start {i} at iteration {final[i]['iteration']}" for i in have]
        parts = [f"{len(have)} with a record ({few(at)})"]
        parts += [f"{len(none)} with none (starts {few(none)})"] if none else []
        checks["starts"] = f"the last record of each of its {n} starts: {', '.join(parts)}"
    return [{**final[i]["design"], **final[i].get("couplings", {})} if i in final else None
            for i in range(1, n + 1)]


def few(items: list, shown: int = 3) -> str:
    """"a, b, c and 517 more": the first ``shown`` of ``items``, and how many more."""
    more = f" and {len(items) - shown} more" if len(items) > shown else ""
    return ", ".join(str(i) for i in items[:shown]) + more


def runs_held(run_ids: list[str], shown: int = 5) -> str:
    """"it holds the iteration records of run(s) a, b" (the first `shown` of them, in recording order)."""
    return f"it holds the iteration records of run{'s' if len(run_ids) > 1 else ''} {few(run_ids, shown)}"


def sweep_phrase(row: dict, n: int) -> str:
    """"the sweep's best design (design 3 of 8, iteration 2 in history)", or its least violated one: counted from 1
    as sweep's notes and sweep.csv's rows count them, with the record's iteration (from 0)."""
    return (f"the sweep's {'best' if row['feasible'] else 'least violated'} design "
            f"(design {row['iteration'] + 1} of {n}, iteration {row['iteration']} in history)")


def records_phrase(rows: list[dict]) -> str:
    """'4 records (iterations 0-3)': a count of records, not of iterations; record 0 is the start, so a
    run that ``optimize`` reports with 'iterations 3' has 4 records."""
    first, last = rows[0].get("iteration"), rows[-1].get("iteration")
    span = f" (iterations {first}-{last})" if first is not None and last is not None else ""
    return f"{len(rows)} record{'s' if len(rows) != 1 else ''}{span}"
