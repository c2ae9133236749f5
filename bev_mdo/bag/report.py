"""PNG plots and a markdown summary of a recorded run, written into the bag directory."""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

from bev_mdo.bag.history import (answered_result, check_note, headline, mda_total, read_answers, records_phrase,
                                  run_ending, sweep_phrase, verified_history)
from bev_mdo.bag.reader import Bag, open_bag
from bev_mdo.mdo.units import label, run_units, unit_of
from bev_mdo.figures import styled, subplots

REQUEST_TYPE = "bev_mdo_msgs/msg/EvaluationRequest"
RESULT_TYPE = "bev_mdo_msgs/msg/EvaluationResult"


def _stamp_ns(header) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def discipline_timing(bag: Bag) -> dict[str, dict[str, list[float]]]:
    """Per discipline: ``compute_time_s`` of each result and request->result latency (s); empty
    requests and results (the coordinator's warm-up) are left out."""
    topics = [t for t, ty in bag.topics.items() if ty in (REQUEST_TYPE, RESULT_TYPE)]
    sent: dict[tuple, int] = {}
    out: dict[str, dict[str, list[float]]] = {}
    for msg, obj in bag.decoded(topics):
        key = (obj.run_id, int(obj.evaluation_id), obj.discipline)
        block = obj.inputs if msg.type_name == REQUEST_TYPE else obj.outputs
        if int(block.batch_size) == 0:
            continue  # the warm-up's empty MDAs: no point evaluated, nothing to time
        if msg.type_name == REQUEST_TYPE:
            for d in list(getattr(obj, "flow", None) or []) or [obj.discipline]:  # a data-flow request: all of them
                sent.setdefault((obj.run_id, int(obj.evaluation_id), d), _stamp_ns(obj.header))
            continue
        entry = out.setdefault(obj.discipline, {"compute_time_s": [], "latency_s": []})
        entry["compute_time_s"].append(float(obj.compute_time_s))
        if key in sent and _stamp_ns(obj.header) and sent[key]:
            entry["latency_s"].append((_stamp_ns(obj.header) - sent[key]) / 1e9)
    return out


def _targets(frame_id: str) -> dict[str, str]:
    """{discipline: instance} a request addresses (a pool's share, mdo/pool.py), from its binding tag
    ``fp:<discipline>=<fingerprint>@<instance>,...``; empty for a request to any instance."""
    if not frame_id.startswith("fp:"):
        return {}
    out = {}
    for entry in frame_id[3:].split(","):
        name, _, rest = entry.partition("=")
        _, sep, inst = rest.partition("@")
        if sep and inst:
            out[name] = inst.lstrip("/")
    return out


def instance_work(bag: Bag) -> dict[str, dict[str, dict]]:
    """Per discipline and instance, from the recorded requests and results (warm-up excluded):
    ``results``, ``points`` (designs answered), ``compute_s`` (summed ``compute_time_s``),
    ``points_per_compute_s`` (throughput while computing), ``failed_points`` (answered not ok),
    and ``unanswered_shares`` / ``unanswered_points``: shares addressed to that instance that it never
    answered (it stalled or died; the coordinator re-sent them to another instance)."""
    topics = [t for t, ty in bag.topics.items() if ty in (REQUEST_TYPE, RESULT_TYPE)]
    addressed: dict[tuple, tuple[str, int]] = {}   # (run, eval id, discipline) -> (instance, points)
    answered: set[tuple] = set()
    work: dict[str, dict[str, dict]] = {}

    def entry(d: str, inst: str) -> dict:
        return work.setdefault(d, {}).setdefault(inst, {"results": 0, "points": 0, "compute_s": 0.0,
                                                        "failed_points": 0, "unanswered_shares": 0,
                                                        "unanswered_points": 0})

    for msg, obj in bag.decoded(topics):
        block = obj.inputs if msg.type_name == REQUEST_TYPE else obj.outputs
        n = int(block.batch_size)
        if n == 0:
            continue
        if msg.type_name == REQUEST_TYPE:
            for d, inst in _targets(obj.header.frame_id).items():
                addressed.setdefault((obj.run_id, int(obj.evaluation_id), d), (inst, n))
            continue
        inst = obj.instance.lstrip("/") or "?"
        answered.add((obj.run_id, int(obj.evaluation_id), obj.discipline, inst))
        e = entry(obj.discipline, inst)
        e["results"] += 1
        e["points"] += n
        e["compute_s"] += float(obj.compute_time_s)
        e["failed_points"] += int(np.size(obj.point_ok) - np.count_nonzero(obj.point_ok))
    for (run, eid, d), (inst, n) in addressed.items():
        if (run, eid, d, inst) not in answered:
            e = entry(d, inst)
            e["unanswered_shares"] += 1
            e["unanswered_points"] += n
    for per in work.values():
        for e in per.values():
            e["compute_s"] = round(e["compute_s"], 6)
            e["points_per_compute_s"] = round(e["points"] / e["compute_s"], 3) if e["compute_s"] > 0 else None
    return work


def _instance_table(work) -> list[str]:
    """The per-instance table of the disciplines served by more than one instance (or with a
    share an instance never answered)."""
    shown = {d: per for d, per in sorted(work.items())
             if len(per) > 1 or any(e["unanswered_shares"] for e in per.values())}
    if not shown:
        return []
    lines = ["", "## Work per instance (worker pools)", "",
             "| discipline | instance | results | points | share of points | compute (s) | points per compute s "
             "| failed points | unanswered shares (points) |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for d, per in shown.items():
        total = sum(e["points"] for e in per.values()) or 1
        for inst, e in sorted(per.items()):
            rate = f"{e['points_per_compute_s']:.1f}" if e["points_per_compute_s"] else "-"
            lines.append(f"| {d} | {inst} | {e['results']} | {e['points']} | {100.0 * e['points'] / total:.1f} % | "
                         f"{e['compute_s']:.3f} | {rate} | {e['failed_points']} | "
                         f"{e['unanswered_shares']} ({e['unanswered_points']}) |")
    lines += ["", "Unanswered shares were addressed to that instance, which never answered them (it stalled "
                  "or left); the coordinator re-sent their designs to the other instances."]
    return lines


def _iterate_markers(ax, it, y, feasible) -> None:
    """Feasible iterates filled, infeasible ones as red crosses (both in the legend)."""
    it, y, feasible = np.asarray(it), np.asarray(y, float), np.asarray(feasible, bool)
    ax.plot(it, y, "-", color="C0", lw=1, alpha=0.6)
    if feasible.any():
        ax.plot(it[feasible], y[feasible], "o", color="C0", ms=4, label="feasible iterate")
    if (~feasible).any():
        ax.plot(it[~feasible], y[~feasible], "x", color="C3", ms=7, mew=1.5, label="infeasible iterate")


def _plot_convergence(rows, path: Path, baseline: dict | None = None, units: dict | None = None):
    it = [r["iteration"] for r in rows]
    feas = [r["feasible"] for r in rows]
    name = rows[0]["objective_name"] or "objective"
    fig, (ax1, ax2) = subplots(2, 1, sharex=True, figsize=(7, 6))
    _iterate_markers(ax1, it, [r["objective"] for r in rows], feas)
    if baseline and name in baseline.get("outputs", {}):
        ax1.axhline(baseline["outputs"][name], color="0.3", ls="-.", lw=1.2, label=f"baseline ({baseline['label']})")
    ax1.set_ylabel(label(name, units or {}))
    ax1.set_title("Objective and constraint convergence")
    ax1.legend(fontsize=8)
    ax2.plot(it, [max(r["max_violation"], 0.0) for r in rows], "o-", ms=3, color="C3")
    ax2.set_yscale("symlog", linthresh=1e-6)
    ax2.set_ylabel("max constraint violation\n(normalised, –)")
    ax2.set_xlabel("iteration")
    for ax in (ax1, ax2):
        ax.grid(True, alpha=0.3)
    return _saved(fig, path)


def _plot_design(rows, path: Path, problem=None, baseline: dict | None = None, units: dict | None = None):
    """Design-variable trajectories with their bounds drawn (a variable on its bound is seen at once)."""
    names = list(dict.fromkeys(n for r in rows for n in r["design"]))
    if problem is not None:  # the config's order (a bag's NamedArray may hold another)
        names = [n for n in problem.names if n in names] + [n for n in names if n not in problem.names]
    dvs = {d.name: d for d in problem.design_variables} if problem is not None else {}

    def bounds(ax, name):
        if name in dvs:
            d = dvs[name]
            ax.axhline(d.lower, color="k", ls="--", lw=1, label=f"bounds [{d.lower:g}, {d.upper:g}]")
            ax.axhline(d.upper, color="k", ls="--", lw=1)
            pad = 0.05 * (d.upper - d.lower)
            ax.set_ylim(d.lower - pad, d.upper + pad)

    return _stacked(rows, "design", names, bounds, baseline, units, path,
                    "Design-variable trajectories (dashed: bounds)")


def _plot_constraints(rows, path: Path, problem=None, baseline: dict | None = None, units: dict | None = None):
    """Each constrained output per iteration with its limit(s) drawn and the infeasible side shaded."""
    names = list(dict.fromkeys(n for r in rows for n in r["constraints"]))
    if problem is not None:
        order = [c.name for c in problem.constraints]
        names = [n for n in order if n in names] + [n for n in names if n not in order]
    if not names:
        return None
    cons = {c.name: c for c in problem.constraints} if problem is not None else {}

    def limits(ax, name):
        c = cons.get(name)
        if c is not None:
            for kind, b in (("lower", c.lower), ("upper", c.upper)):
                if b is None:
                    continue
                ax.axhline(b, color="C3", ls="--", lw=1.2, label=f"limit {'≥' if kind == 'lower' else '≤'} {b:g}")
                lo, hi = ax.get_ylim()
                if kind == "lower":
                    ax.axhspan(min(lo, b), b, color="C3", alpha=0.08)
                else:
                    ax.axhspan(b, max(hi, b), color="C3", alpha=0.08)

    return _stacked(rows, "constraints", names, limits, baseline, units, path,
                    "Constrained outputs (dashed: limits; shaded: infeasible side)")


def _stacked(rows, key: str, names, draw_limits, baseline, units, path: Path, title: str):
    """One panel per name: the iterates of ``row[key][name]``, what `draw_limits(ax, name)` draws, and the
    baseline's value (its design for "design", its outputs otherwise)."""
    fig, axes = subplots(len(names), 1, sharex=True, figsize=(7, 1.9 * len(names) + 1), squeeze=False)
    it = [r["iteration"] for r in rows]
    feas = [r["feasible"] for r in rows]
    base = (baseline or {}).get("design" if key == "design" else "outputs", {})
    for ax, name in zip(axes[:, 0], names):
        _iterate_markers(ax, it, [r[key].get(name, np.nan) for r in rows], feas)
        draw_limits(ax, name)
        if name in base:
            ax.axhline(base[name], color="0.3", ls="-.", lw=1.2, label=f"baseline ({baseline['label']})")
        ax.set_ylabel(label(name, units or {}), fontsize=8)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    axes[0, 0].set_title(title)
    axes[-1, 0].set_xlabel("iteration")
    return _saved(fig, path)


def _saved(fig, path: Path):
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    return fig


def _plot_timing(timing, path: Path):
    names = sorted(timing)
    fig, (ax1, ax2) = subplots(1, 2, figsize=(10, 4))
    ax1.boxplot([np.array(timing[n]["compute_time_s"]) * 1e3 for n in names], tick_labels=names)
    ax1.set_ylabel("compute time per batch (ms)")
    ax1.set_title("Discipline compute time (warm-up excluded)")
    lat = [np.array(timing[n]["latency_s"]) * 1e3 for n in names]
    if any(len(v) for v in lat):
        ax2.boxplot([v if len(v) else [np.nan] for v in lat], tick_labels=names)
    ax2.set_ylabel("request → result latency (ms)")
    ax2.set_title("Round trip (header stamps)")
    for ax in (ax1, ax2):
        ax.tick_params(axis="x", rotation=30)
        ax.grid(True, alpha=0.3)
    return _saved(fig, path)


def _timing_table(timing) -> list[str]:
    lines = ["| discipline | results | compute mean (ms) | compute p95 (ms) | latency p50 (ms) | latency p95 (ms) |",
             "|---|---:|---:|---:|---:|---:|"]
    for name in sorted(timing):
        c = np.array(timing[name]["compute_time_s"]) * 1e3
        lat = np.array(timing[name]["latency_s"]) * 1e3
        lp = (f"{np.percentile(lat, 50):.3f} | {np.percentile(lat, 95):.3f}" if lat.size else "- | -")
        lines.append(f"| {name} | {c.size} | {c.mean():.3f} | {np.percentile(c, 95):.3f} | {lp} |")
    return lines


def _context(bag: Bag, checks: dict | None = None):
    """(config, problem) from the config stored in the bag; Nones where the bag has no config or it
    no longer loads here (then ``checks["config"]`` says why: the report has no units, analysis or answers)."""
    if not bag.stored_config.text:
        return None, None
    try:
        from bev_mdo.config import RunConfig

        config = RunConfig.load(bag.stored_config.data)
        config.disciplines  # noqa: B018 - the user's classes: loaded here, or said why not
        return config, config.problem
    except Exception as exc:  # noqa: BLE001 - a report is written even if the model no longer loads
        if checks is not None:  # e.g. a user module on a search path relative to where the run was
            checks["config"] = (f"the config stored in the bag does not load here ({str(exc).splitlines()[0]}): "
                                "the report has no units, final analysis or answers")
        return None, None


def _units(config) -> dict:
    """{variable: unit} as the recorded config's disciplines declare them ({} if it no longer loads)."""
    if config is None:
        return {}
    try:
        return run_units(config.disciplines)
    except Exception:  # noqa: BLE001 - a report is written even if the model no longer loads
        return {}


def bag_units(bag: Bag) -> dict:
    """{variable: unit} declared by the disciplines of the config stored in the bag ({} without one)."""
    return _units(_context(bag)[0])


def _analyse(config, design: dict) -> dict | None:
    """One in-process MDA of ``design`` (the report's mass, cost, ... of the final iterate)."""
    try:
        from bev_mdo.mdo.driver import evaluate_design
        from bev_mdo.mdo.evaluator import InProcessEvaluator

        return evaluate_design(config.settings, InProcessEvaluator(config.timed_disciplines()), design)
    except Exception:  # noqa: BLE001 - a report is written even if the model no longer runs
        return None


def _baseline(config, problem) -> dict | None:
    """The config's own ``problem.baseline`` analysed in process; None when the config names none."""
    base = config.baseline
    if not base:
        return None
    design = {n: base["design"].get(n, d.initial) for n, d in zip(problem.names, problem.design_variables)}
    res = _analyse(config, design)
    if res is None:
        return None
    return {"label": base["name"], "design": design, "outputs": res["outputs"]}


def _answers_section(answers: dict | None, point: str = "the end point") -> list[str]:
    if not answers:
        return []
    held = "the design" if point != "the last recorded iterate" else point
    head = f"What holds {held}" if answers.get("feasible") else f"Why {point} is infeasible"
    out = ["", f"## {head}", ""]
    out += [f"- {line.strip()}" if not line.startswith("  ") else f"  - {line.strip()}" for line in answers["lines"]]
    return out


def _markdown(bag: Bag, rows, timing, images: list[str], final: dict | None = None,
              answers: dict | None = None, baseline: dict | None = None, units: dict | None = None,
              k: int = -1, ending: tuple[bool, str] | None = None, config_note: str = "", said: str = "",
              run_id: str | None = None) -> str:
    """``ending``: (finished, how the run ended: history.run_ending), said first; None for a sweep. ``said``: what
    the reading left out or could not verify (history.check_note). ``run_id``: the run read (--run-id), else the bag's."""
    info = bag.info
    finished = ending is None or ending[0]
    lines = [f"# Run report: {bag.bag_dir.name}", "", *([f"- {ending[1]}"] if ending else []),
             f"- bag file: `{bag.mcap_path.name}` ({bag.file_size} bytes, {bag.message_count} messages, "
             f"{bag.duration_ns / 1e9:.3f} s recorded)",
             f"- run id: `{run_id or info.get('run_id') or '?'}`, bev_mdo version `{info.get('version', '?')}`",
             *([f"- **{config_note}**"] if config_note else []), *([f"- **{said}**"] if said else [])]
    if bag.truncated:
        lines.append(f"- **truncated**: {bag.recovery_note()}")
    if rows:
        last, sweep = rows[k], rows[-1]["formulation"] == "doe"
        recorded = [r for r in rows if not r.get("from_answers")]  # the result the bag lacks is the answers' word
        feasible = [r for r in rows if r["feasible"]] if not sweep else []  # a sweep's headline is its best
        lines += [f"- {records_phrase(recorded)}, formulation `{last['formulation']}`, optimizer "
                  f"`{last['optimizer']}`, {mda_total(recorded, answers)}", ""]
        result = not sweep and (k % len(rows) != len(rows) - 1 or last.get("from_answers"))  # not the last record
        where = "iteration not recorded" if last["iteration"] is None else f"iteration {last['iteration']}"
        point = (sweep_phrase(last, len(rows)) if sweep else f"the run's result ({where}, from its end-of-run record)"
                 if last.get("from_answers") else f"the run's result ({where})"
                 if result else "the end point" if finished else "the last recorded iterate")
        lines += [f"## The {point[4:]}" if sweep or result else "## Final iterate" if finished else
                  "## Last recorded iterate (" + ("how the run ended is not known)" if ending and ending[0] is None
                                                  else "the run did not finish)"), ""]
        base = baseline or {}
        bcol = f" {base['label']} |" if base else ""
        lines += [f"| quantity | unit | value |{bcol}", "|---|---|---:|" + ("---:|" if base else "")]

        def row(k, v, ref):
            extra = (" |" if ref is None else f" {ref:.6g} |") if base else ""
            return f"| {k} | {unit_of(k, units or {})} | {v:.6g} |{extra}"

        lines.append(row(last["objective_name"] or "objective", last["objective"],
                         base.get("outputs", {}).get(last["objective_name"])))
        lines += [row(k, v, base.get("design", {}).get(k)) for k, v in last["design"].items()]
        shown = {last["objective_name"], *last["design"]}
        if final is not None:
            lines += [row(k, v, base.get("outputs", {}).get(k)) for k, v in final["outputs"].items() if k not in shown]
        else:
            lines += [row(k, v, base.get("outputs", {}).get(k)) for k, v in last["constraints"].items()]
        viol = "not recorded" if last.get("from_answers") and last["max_violation"] != last["max_violation"] else \
            f"{last['max_violation']:.3g}"  # the answers predate it
        lines += [f"| max violation (normalised) | – | {viol} |" + (" |" if base else ""),
                  f"| feasible | | {last['feasible']} |" + (" |" if base else "")]
        if final is not None:
            lines += ["", "The objective is the recorded one; the other outputs (constraints, mass, cost, ...) are "
                          f"{'this design' if sweep or last.get('from_answers') else 'this iterate'} analysed again in process "
                          "from the configuration stored in the bag (an IDF iterate away from consistency differs from "
                          "its record there: `history` shows the recorded values)."]
        if feasible:
            from bev_mdo.mdo.driver import BEST_REL_TOL, pick_result

            sign = -1.0 if bag.stored_config.maximized else 1.0
            # the run's result where the bag stores its design (the rule's 'converged' is not recorded)
            at = [r for r in rows if r["feasible"] and r["design"] == (answers or {}).get("result_design")]
            best = at[-1] if at else rows[pick_result(rows, sign, converged=False)]
            spot = (f"iteration {best['iteration']}" if best["iteration"] is not None else
                    "the run's result, from its end-of-run record")
            lines += ["", f"Best feasible objective {best['objective']:.6g} at {spot}"
                          f"{' (maximised)' if sign < 0 else ''} (" + ("the run's result)." if at else
                          f"an earlier iterate counts only if better by more than {BEST_REL_TOL:g} relative, "
                          "as for the run's result).")]
        lines += _answers_section(answers, point)
    else:
        lines += ["", "No iteration records in this bag."]
    lines += ["", "## Topics", "", "| topic | type | messages |", "|---|---|---:|"]
    lines += [f"| {t} | {ty} | {bag.counts.get(t, 0)} |" for t, ty in sorted(bag.topics.items())]
    if timing:
        lines += ["", "## Discipline evaluation time (warm-up excluded)", "", *_timing_table(timing)]
    lines += _instance_table(instance_work(bag))
    lines += ["", "## Plots", ""] + [f"![{Path(p).stem}]({p})" for p in images]
    if bag.stored_config.text:
        lines += ["", "## Configuration (as recorded)", "", "```yaml", bag.stored_config.text.rstrip(), "```"]
    return "\n".join(lines) + "\n"


def _inconsistent(row: dict, final: dict | None, tol: float) -> list[str]:
    """An infeasible IDF record's couplings that are not what its disciplines give at its design (``final``: the
    design analysed through), beyond ``tol`` relative: one line each (its constraints and objective were taken
    at the optimiser's values; the record's largest violation was such a residual, named nowhere)."""
    outputs = (final or {}).get("outputs", {})
    if row["feasible"] or row.get("formulation") != "idf":
        return []
    return [f"not consistent: {c} is {v:.6g} in the optimiser's variables, {outputs[c]:.6g} from its disciplines at "
            "this design" for c, v in (row.get("couplings") or {}).items()
            if c in outputs and abs(v - outputs[c]) > tol * max(1.0, abs(outputs[c]))]


@styled
def report(bag, out_dir=None, run_id: str | None = None, checks: dict | None = None, key_file: str | None = None,
           no_verify: bool = False) -> list[Path]:
    """Write plots and ``report.md`` of the bag's own run (or `run_id`; its iteration records
    verified, see ``history``) into ``out_dir`` (default: the bag's folder; for another run than the bag's own,
    its ``report_<run_id>`` folder); returns the written paths."""
    bag = bag if isinstance(bag, Bag) else open_bag(bag)
    # one run of a recording of several: its own folder, so that reporting another run does not overwrite it
    own = not run_id or run_id == bag.info.get("run_id")
    out = Path(out_dir) if out_dir else bag.bag_dir if own else \
        bag.bag_dir / ("report_" + re.sub(r"[^A-Za-z0-9_.-]", "_", run_id).lstrip("."))  # '../x' stays inside
    rows, signer = verified_history(bag, run_id, checks=checks, key_file=key_file, no_verify=no_verify)
    checks = {} if checks is None else checks
    checks["iterations"] = len(rows)
    if not rows and not own:  # a run the bag does not hold: nothing of it to write (a report_<typo> folder said
        return []             # "the run did not finish" of a run nothing is known of, with the bag's timings)
    out.mkdir(parents=True, exist_ok=True)
    timing = discipline_timing(bag)
    config, problem = _context(bag, checks)
    final = answers = baseline = None
    units = _units(config)
    answers = read_answers(bag, signer, checks)  # a signed run's count only when signed with its key too
    ending = run_ending(bag, rows, answers, checks)  # before the report makes answers of its own
    told = answered_result(rows, answers)  # the result's record is not in the bag (its recorder died): the answers'
    shown = rows + [told] if told else rows
    k = headline(shown, -1.0 if bag.stored_config.maximized else 1.0, answers)  # the result, a sweep's best, the last
    if rows and config is not None:
        final = _analyse(config, dict(shown[k]["design"]))
        baseline = _baseline(config, problem)
        if answers is None:
            from bev_mdo.mdo.active import answers_for

            values = dict(final["outputs"]) if final else {}
            values.update(shown[k]["constraints"])
            try:
                answers = answers_for(config.settings, dict(shown[k]["design"]), values,
                                      config.disciplines, units=units)
            except Exception:  # noqa: BLE001
                answers = None
            tol = float(config.settings.optimizer.feasibility_tolerance)
            off = _inconsistent(shown[k], final, tol)
            if answers and answers["feasible"] and not off and not shown[k]["feasible"] and \
                    shown[k]["formulation"] == "idf" and shown[k]["max_violation"] > tol:  # scaled otherwise than here
                off = [f"not consistent: the record's largest violation {shown[k]['max_violation']:.3g} is in none of "
                       "its constraints or bounds, so it is an IDF consistency residual"]
            if answers and off:  # its constraints may hold at the optimiser's couplings: "What holds" followed
                answers["feasible"], answers["lines"] = False, [*off, *answers["lines"]]
    if told is not None:  # answers stored before they held the result's objective: the analysis gives it
        outputs = (final or {}).get("outputs", {})
        told["objective"] = outputs.get(told["objective_name"], float("nan")) if told["objective"] is None \
            else told["objective"]
        told["max_violation"] = float("nan") if told["max_violation"] is None else told["max_violation"]
    written: list[Path] = []
    if rows:
        _plot_convergence(rows, out / "convergence.png", baseline, units)
        _plot_design(rows, out / "design.png", problem, baseline, units)
        written += [out / "convergence.png", out / "design.png"]
        if _plot_constraints(rows, out / "constraints.png", problem, baseline, units) is not None:
            written.append(out / "constraints.png")
    if timing:
        _plot_timing(timing, out / "discipline_time.png")
        written.append(out / "discipline_time.png")
    md = out / "report.md"
    # what was left out or could not be verified, as stderr says it (a forged record dropped, a stored config that
    # does not load): report.md said "the run finished" and nothing of it
    # (an unsigned run, in process or a sweep without a key, is read unverified as docs/security.md says: no warning)
    said = "; ".join(filter(None, [check_note({c: v for c, v in checks.items() if c not in ("config", "unverified")}),
                                   bag.metadata_note]))
    md.write_text(_markdown(bag, shown, timing, [p.name for p in written], final, answers, baseline, units, k, ending,
                            checks.get("config", ""), said, run_id), encoding="utf-8")
    return written + [md]
