"""PNG plots and a markdown summary of a recorded run, written into the bag directory."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from bev_mdo.bag.history import history
from bev_mdo.bag.reader import Bag, open_bag, read_config

REQUEST_TYPE = "bev_mdo_msgs/msg/EvaluationRequest"
RESULT_TYPE = "bev_mdo_msgs/msg/EvaluationResult"


def _stamp_ns(header) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def discipline_timing(bag: Bag) -> dict[str, dict[str, list[float]]]:
    """Per discipline: ``compute_time_s`` of each result and request->result latency (s)."""
    topics = [t for t, ty in bag.topics.items() if ty in (REQUEST_TYPE, RESULT_TYPE)]
    sent: dict[tuple, int] = {}
    out: dict[str, dict[str, list[float]]] = {}
    for msg, obj in bag.decoded(topics):
        key = (obj.run_id, int(obj.evaluation_id), obj.discipline)
        if msg.type_name == REQUEST_TYPE:
            for d in list(getattr(obj, "flow", None) or []) or [obj.discipline]:  # a data-flow request: all of them
                sent.setdefault((obj.run_id, int(obj.evaluation_id), d), _stamp_ns(obj.header))
            continue
        entry = out.setdefault(obj.discipline, {"compute_time_s": [], "latency_s": []})
        entry["compute_time_s"].append(float(obj.compute_time_s))
        if key in sent and _stamp_ns(obj.header) and sent[key]:
            entry["latency_s"].append((_stamp_ns(obj.header) - sent[key]) / 1e9)
    return out


def _plot_convergence(rows, path: Path) -> None:
    import matplotlib.pyplot as plt

    it = [r["iteration"] for r in rows]
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
    ax1.plot(it, [r["objective"] for r in rows], "o-", ms=3)
    ax1.set_ylabel(rows[0]["objective_name"] or "objective")
    ax1.set_title("Objective and constraint convergence")
    ax2.plot(it, [max(r["max_violation"], 0.0) for r in rows], "o-", ms=3, color="C3")
    ax2.set_yscale("symlog", linthresh=1e-6)
    ax2.set_ylabel("max constraint violation")
    ax2.set_xlabel("iteration")
    for ax in (ax1, ax2):
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _plot_design(rows, path: Path) -> None:
    import matplotlib.pyplot as plt

    names = list(dict.fromkeys(n for r in rows for n in r["design"]))
    fig, axes = plt.subplots(len(names), 1, sharex=True, figsize=(7, 1.8 * len(names) + 1),
                             squeeze=False)
    it = [r["iteration"] for r in rows]
    for ax, name in zip(axes[:, 0], names):
        ax.plot(it, [r["design"].get(name, np.nan) for r in rows], "o-", ms=3)
        ax.set_ylabel(name)
        ax.grid(True, alpha=0.3)
    axes[0, 0].set_title("Design-variable trajectories")
    axes[-1, 0].set_xlabel("iteration")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _plot_timing(timing, path: Path) -> None:
    import matplotlib.pyplot as plt

    names = sorted(timing)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    ax1.boxplot([np.array(timing[n]["compute_time_s"]) * 1e3 for n in names], tick_labels=names)
    ax1.set_ylabel("compute time per batch (ms)")
    ax1.set_title("Discipline compute time")
    lat = [np.array(timing[n]["latency_s"]) * 1e3 for n in names]
    if any(len(v) for v in lat):
        ax2.boxplot([v if len(v) else [np.nan] for v in lat], tick_labels=names)
    ax2.set_ylabel("request -> result latency (ms)")
    ax2.set_title("Round trip (header stamps)")
    for ax in (ax1, ax2):
        ax.tick_params(axis="x", rotation=30)
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _timing_table(timing) -> list[str]:
    lines = ["| discipline | results | compute mean (ms) | compute p95 (ms) | latency p50 (ms) | latency p95 (ms) |",
             "|---|---:|---:|---:|---:|---:|"]
    for name in sorted(timing):
        c = np.array(timing[name]["compute_time_s"]) * 1e3
        lat = np.array(timing[name]["latency_s"]) * 1e3
        lp = (f"{np.percentile(lat, 50):.3f} | {np.percentile(lat, 95):.3f}" if lat.size else "- | -")
        lines.append(f"| {name} | {c.size} | {c.mean():.3f} | {np.percentile(c, 95):.3f} | {lp} |")
    return lines


def _markdown(bag: Bag, rows, timing, images: list[str]) -> str:
    info = bag.info
    lines = [f"# Run report: {bag.bag_dir.name}", "",
             f"- bag file: `{bag.mcap_path.name}` ({bag.file_size} bytes, {bag.message_count} messages, "
             f"{bag.duration_ns / 1e9:.3f} s recorded)",
             f"- run id: `{info.get('run_id', '?')}`, bev_mdo version `{info.get('version', '?')}`"]
    if bag.truncated:
        lines.append(f"- **truncated**: {bag.recovery_note()}")
    if rows:
        last = rows[-1]
        feasible = [r for r in rows if r["feasible"]]
        lines += [f"- {len(rows)} iterations, formulation `{last['formulation']}`, optimizer "
                  f"`{last['optimizer']}`, {last['mda_evaluations']} multidisciplinary evaluations", "",
                  "## Final iterate", "", "| quantity | value |", "|---|---:|",
                  f"| {last['objective_name'] or 'objective'} | {last['objective']:.6g} |",
                  *[f"| {k} | {v:.6g} |" for k, v in last["design"].items()],
                  *[f"| constraint {k} | {v:.6g} |" for k, v in last["constraints"].items()],
                  f"| max violation | {last['max_violation']:.3g} |",
                  f"| feasible | {last['feasible']} |"]
        if feasible:
            best = min(feasible, key=lambda r: r["objective"])
            lines += ["", f"Best feasible objective {best['objective']:.6g} at iteration {best['iteration']}."]
    else:
        lines += ["", "No iteration records in this bag."]
    lines += ["", "## Topics", "", "| topic | type | messages |", "|---|---|---:|"]
    lines += [f"| {t} | {ty} | {bag.counts.get(t, 0)} |" for t, ty in sorted(bag.topics.items())]
    if timing:
        lines += ["", "## Discipline evaluation time", "", *_timing_table(timing)]
    lines += ["", "## Plots", ""] + [f"![{Path(p).stem}]({p})" for p in images]
    config = read_config(bag)
    if config:
        lines += ["", "## Configuration (as recorded)", "", "```yaml", config.rstrip(), "```"]
    return "\n".join(lines) + "\n"


def report(bag, out_dir=None, run_id: str | None = None, checks: dict | None = None) -> list[Path]:
    """Write plots and ``report.md`` of the bag's own run (or `run_id`; its iteration records
    verified, see ``history``); returns the written paths."""
    import matplotlib

    matplotlib.use("Agg")
    bag = bag if isinstance(bag, Bag) else open_bag(bag)
    out = Path(out_dir) if out_dir else bag.bag_dir
    out.mkdir(parents=True, exist_ok=True)
    rows = history(bag, run_id, checks=checks)
    timing = discipline_timing(bag)
    written: list[Path] = []
    if rows:
        _plot_convergence(rows, out / "convergence.png")
        _plot_design(rows, out / "design.png")
        written += [out / "convergence.png", out / "design.png"]
    if timing:
        _plot_timing(timing, out / "discipline_time.png")
        written.append(out / "discipline_time.png")
    md = out / "report.md"
    md.write_text(_markdown(bag, rows, timing, [p.name for p in written]), encoding="utf-8")
    return written + [md]
