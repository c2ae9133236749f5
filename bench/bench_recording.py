"""Recording overhead: optimisation wall time over ROS with and without the recorder node.

  . scripts/env.sh && python bench/bench_recording.py [--runs 5] [--optimizer SLSQP]

Runs `bev-mdo optimize` alternately with and without recording (each run starts its own
nodes on domain 63, localhost only) and compares the medians of the optimisation wall time
reported by the coordinator (start-up and discovery excluded). Also prints bag size per
multidisciplinary evaluation.
"""
from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))


def main() -> int:
    from bev_mdo.testing import ros_env

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--optimizer", default="SLSQP")
    ap.add_argument("--domain-id", type=int, default=63)
    ap.add_argument("--json", default=None, help="results file (default bench/results/recording.json)")
    args = ap.parse_args()
    env = ros_env(args.domain_id)
    times = {"record": [], "no-record": []}
    sizes = []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.runs):
            for mode in ("record", "no-record"):
                bag = Path(tmp) / f"run{i}"
                cmd = [sys.executable, "-m", "bev_mdo", "optimize", str(REPO / "config" / "leaf_nedc.yaml"),
                       "--json", "--quiet", "--domain-id", str(args.domain_id), "--optimizer", args.optimizer]
                cmd += ["--bag", str(bag)] if mode == "record" else ["--no-record"]
                out = subprocess.run(cmd, env=env, cwd=tmp, capture_output=True, text=True, timeout=600)
                if out.returncode != 0:
                    print(out.stderr[-2000:], file=sys.stderr)
                    return 1
                res = json.loads(out.stdout)
                times[mode].append(res["wall_time_s"])
                if mode == "record":
                    # the bag itself (the run's directory also holds logs/ and answers.json)
                    size = sum(f.stat().st_size for f in bag.iterdir()
                               if f.is_file() and (f.suffix == ".mcap" or f.name == "metadata.yaml"))
                    sizes.append(size / res["mda_evaluations"])
    rec, plain = statistics.median(times["record"]), statistics.median(times["no-record"])
    figures = {"optimizer": args.optimizer, "runs": args.runs,
               "median_wall_s_recording": rec, "median_wall_s_not_recording": plain,
               "overhead_percent": 100 * (rec - plain) / plain,
               "bag_bytes_per_mda_evaluation": statistics.median(sizes),
               "all_wall_s": times}
    print(json.dumps(figures, indent=2))
    sys.path.insert(0, str(REPO / "bench"))
    import _results

    ratios = [100 * (r / p - 1) for r, p in zip(times["record"], times["no-record"])]
    _results.write("recording", [
        _results.figure(f"optimiser wall time over ROS, {args.optimizer}, recorded", "s", times["record"]),
        _results.figure(f"optimiser wall time over ROS, {args.optimizer}, not recorded", "s", times["no-record"]),
        _results.figure("recording overhead, run by run (recorded / not recorded - 1)", "%", ratios, "<= 5"),
        _results.figure("bag size per multidisciplinary evaluation", "B", sizes)], path=args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
