"""Recording overhead: optimisation wall time over ROS with and without the recorder node.

  . scripts/env.sh && python bench/bench_recording.py [--runs 5] [--optimizer SLSQP] [--domain-id 63]

Runs `bev-mdo optimize` alternately with and without recording (each run starts its own nodes on
the domain, localhost only) in both layouts, side by side: the default (`--compose coordinator`,
the disciplines' nodes in the command's process) and a process per discipline (`--compose none`).
Compares the optimisation wall time reported by the coordinator (start-up and discovery excluded),
run by run. In the default layout a run without a recorder hands its requests to the nodes by direct
call (no other reader on the topics: ros/composed.py), and a recorded one goes over DDS so that the
recorder gets every message: there the figure is the price of recording, DDS included. With a process
per discipline both go over DDS: the recorder's own cost. Also prints the bag size per
multidisciplinary evaluation.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
LAYOUTS = {"coordinator": "nodes in the command's process (default)", "none": "a process per discipline"}


def main() -> int:
    from bev_mdo.testing import ros_env

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--optimizer", default="SLSQP")
    ap.add_argument("--domain-id", type=int, default=63)
    ap.add_argument("--json", default=None, help="results file (default bench/results/recording.json)")
    args = ap.parse_args()
    env = ros_env(args.domain_id)
    times = {(layout, mode): [] for layout in LAYOUTS for mode in ("record", "no-record")}
    sizes = []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.runs):
            for layout in LAYOUTS:
                for mode in ("record", "no-record"):
                    bag = Path(tmp) / f"run{i}_{layout}"
                    cmd = [sys.executable, "-m", "bev_mdo", "optimize", str(REPO / "config" / "leaf_nedc.yaml"),
                           "--json", "--quiet", "--domain-id", str(args.domain_id), "--optimizer", args.optimizer,
                           "--compose", layout]
                    cmd += ["--bag", str(bag)] if mode == "record" else ["--no-record"]
                    out = subprocess.run(cmd, env=env, cwd=tmp, capture_output=True, text=True, timeout=600)
                    if out.returncode != 0:
                        print(out.stderr[-2000:], file=sys.stderr)
                        return 1
                    res = json.loads(out.stdout)
                    times[(layout, mode)].append(res["wall_time_s"])
                    if mode == "record":
                        # the bag itself (the run's directory also holds logs/ and answers.json)
                        size = sum(f.stat().st_size for f in bag.iterdir()
                                   if f.is_file() and (f.suffix == ".mcap" or f.name == "metadata.yaml"))
                        sizes.append(size / res["mda_evaluations"])
    print(json.dumps({f"{layout} {mode}": v for (layout, mode), v in times.items()}, indent=2))
    sys.path.insert(0, str(REPO / "bench"))
    import _results

    figures = []
    for layout, label in LAYOUTS.items():
        rec, plain = times[(layout, "record")], times[(layout, "no-record")]
        figures += [_results.figure(f"optimiser wall time over ROS, {args.optimizer}, {label}, recorded", "s", rec),
                    _results.figure(f"optimiser wall time over ROS, {args.optimizer}, {label}, not recorded", "s", plain)]
    # the recorder's own cost: both runs over DDS (in the default layout a run without a recorder
    # skips DDS altogether, so its ratio prices DDS as much as recording; it is in the JSON)
    ratios = {layout: [100 * (r / p - 1) for r, p in zip(times[(layout, "record")], times[(layout, "no-record")])]
              for layout in LAYOUTS}
    figures.append(_results.figure("recording overhead, a process per discipline, run by run "
                                   "(recorded / not recorded - 1)", "%", ratios["none"], "<= 5"))
    _results.write("recording", figures, path=args.json, extra={
        "overhead_percent_default_layout": ratios["coordinator"],
        "bag_bytes_per_mda_evaluation": _results.figure("bag size per multidisciplinary evaluation", "B", sizes)})
    return 0


if __name__ == "__main__":
    sys.exit(main())
