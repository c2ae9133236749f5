"""Start to result over ROS: a loop against a feed-forward graph.

Times the whole command a user runs, ``bev-mdo optimize CONFIG --json --no-record --quiet``
over ROS (node processes started, discovery, the handshake, warm-up, the optimisation, the
result on stdout, every process stopped), for:

- ``leaf_nedc``: the default BEV problem, a feed-forward graph (data flow: one request per MDA);
- ``leaf_nedc_sized``: the same with ``problem.battery_sized_for_range: true`` (a loop through
  battery_sizing: Gauss-Seidel, hub and spoke);
- ``sellar_mdf``: examples/sellar/sellar_mdf.yaml (a loop y1 <-> y2; user disciplines).

Once, a loop stalled ~40 s at start (two data-flow warm-ups no node of a loop can
answer, each waiting timeout x (retries + 1)); now a loop is probed hub and spoke only.
Runs are interleaved round by round (the host is noisy); median, min and max per config.
The in-process run of each config is timed the same way, for reference. Asserts nothing.

``--concurrent 1,4,8``: start-up of N runs started together on ONE domain, each
``bev-mdo optimize config/leaf_nedc.yaml --bag ...`` (recorded, as a user runs it), with a process per
discipline (``--compose none``) and composed into the coordinator (``--compose coordinator``). Start-up
is the time from starting the command to its first iteration line; every run's optimum is checked
against the others of its round (the answer must not depend on the layout or the crowd). The figures
go into ``bench/results/bench_sellar_startup.json`` (median, min and max over ``--repeat`` rounds of every run's
start-up; failed runs counted).

    .venv/bin/python bench/bench_sellar_startup.py [--repeat 5] [--domain-id 22]
    .venv/bin/python bench/bench_sellar_startup.py --concurrent 1,4,8 --repeat 2 [--compose none,coordinator]
    (take /tmp/bev_ros_tests.lock around it on a shared host; ``--append`` adds this call's rounds to
    those already in the results file, so each round can run under the lock on its own)
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]
RESULT = REPO / "bench" / "results" / "bench_sellar_startup.json"
ROUND_TIMEOUT_S = 300.0  # a round of runs started together is stopped after this
RUN_ADDRESS_SPACE = 4 << 30  # bytes of address space each process of a run may map (a load test is bounded)


def _bounded() -> None:
    """In a run's command (its nodes inherit it): the address-space bound. Nothing else changes: the
    command stays in the bench's session, as runs started from one shell do (docs/scaling.md)."""
    import resource

    resource.setrlimit(resource.RLIMIT_AS, (RUN_ADDRESS_SPACE, RUN_ADDRESS_SPACE))


def configs(tmp: Path) -> dict[str, Path]:
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["problem"]["battery_sized_for_range"] = True
    raw["name"] = "leaf_nedc_sized"
    sized = tmp / "leaf_nedc_sized.yaml"
    sized.write_text(yaml.safe_dump(raw, sort_keys=False))
    return {"leaf_nedc": REPO / "config" / "leaf_nedc.yaml", "leaf_nedc_sized": sized,
            "sellar_mdf": REPO / "examples" / "sellar" / "sellar_mdf.yaml"}


def run_once(path: Path, transport: str, domain: int, cwd: Path) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    argv = [sys.executable, "-m", "bev_mdo", "optimize", str(path), "--json", "--quiet", "--no-record",
            "--transport", transport, *(["--domain-id", str(domain)] if transport == "ros" else [])]
    t0 = time.perf_counter()
    p = subprocess.run(argv, env=env, cwd=cwd, capture_output=True, text=True, timeout=600)
    wall = time.perf_counter() - t0
    if p.returncode not in (0, 1):
        raise SystemExit(f"{path.name} ({transport}) failed with {p.returncode}: {p.stderr.strip()[-500:]}")
    doc = json.loads(p.stdout)
    warnings = [ln for ln in p.stderr.splitlines() if "retry" in ln or "WARN" in ln]
    return {"wall_s": wall, "optimisation_s": doc["wall_time_s"], "objective": doc["objective"],
            "iterations": doc["iterations"], "feasible": doc["feasible"],
            "retried": doc.get("retried_requests", 0), "warnings": warnings}


def start_together(n: int, compose: str, domain: int, cwd: Path, tag: str) -> list[dict]:
    """N recorded leaf_nedc runs started at once on one domain: each one's start-up (s to its first
    iteration line), wall time and objective."""
    import threading

    env = dict(os.environ)
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.pop("ROS_LOG_DIR", None)
    out: list[dict] = [{} for _ in range(n)]
    load = round(os.getloadavg()[0], 2)  # the host's load as the round starts

    def one(k: int, t0: float, p: subprocess.Popen) -> None:
        first, tail = None, []
        for line in p.stderr:
            if first is None and line.startswith("iter "):
                first = time.perf_counter() - t0
            tail = (tail + [line.rstrip()])[-3:]
        p.wait()
        doc = json.loads(p.stdout.read() or "{}") if p.returncode == 0 else {}
        out[k] = {"startup_s": first, "wall_s": time.perf_counter() - t0, "exit": p.returncode, "load_1min": load,
                  "objective": doc.get("objective"), **({"stderr_tail": tail} if p.returncode else {})}

    threads, procs = [], []
    for k in range(n):
        argv = [sys.executable, "-m", "bev_mdo", "optimize", str(REPO / "config" / "leaf_nedc.yaml"), "--json",
                "--domain-id", str(domain), "--compose", compose, "--bag", str(cwd / "bags" / f"{tag}_{k}")]
        t0 = time.perf_counter()
        p = subprocess.Popen(argv, env=env, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             preexec_fn=_bounded)
        threads.append(threading.Thread(target=one, args=(k, t0, p)))
        threads[-1].start()
        procs.append(p)
    deadline = time.monotonic() + ROUND_TIMEOUT_S
    for t in threads:
        t.join(timeout=max(0.0, deadline - time.monotonic()))
    for p in procs:  # a run still going after the bound is stopped (SIGTERM: it stops its nodes) and counts as failed
        if p.poll() is None:
            p.terminate()
            try:
                p.wait(timeout=60)
            except subprocess.TimeoutExpired:
                p.kill()
    for t in threads:
        t.join()
    return out


def concurrent(args) -> int:
    """``--concurrent``: figures (median and range of every run's start-up, per count and layout) into
    ``bench/results/bench_sellar_startup.json`` (bench/_results.py; the one-run ``rows`` kept), rendered into
    docs/performance.md."""
    sys.path.insert(0, str(REPO / "bench"))
    from _results import figure, write

    counts = [int(c) for c in args.concurrent.split(",")]
    composes = args.compose.split(",")
    runs: dict[tuple[int, str], list[list[dict]]] = {}
    with tempfile.TemporaryDirectory() as d:
        for r in range(args.repeat):
            for n in counts:
                for compose in composes:  # interleaved: noisy host
                    rs = start_together(n, compose, args.domain_id, Path(d), f"r{r}_{n}_{compose}")
                    runs.setdefault((n, compose), []).append(rs)
                    ok = [x for x in rs if x["exit"] == 0]
                    print(f"round {r}: {n} x --compose {compose}: {len(ok)}/{n} finished; start-up "
                          f"{sorted(round(x['startup_s'], 1) for x in ok if x['startup_s'])} s", flush=True)
    if args.append and RESULT.exists():  # the rounds of earlier calls first
        for key, rounds in json.loads(RESULT.read_text(encoding="utf-8")).get("raw", {}).items():
            n, c = key.split("|")
            runs[(int(n), c)] = rounds + runs.get((int(n), c), [])
    figures, failed, objectives = [], {}, set()
    runs = dict(sorted(runs.items()))  # by count, then layout
    for (n, compose), rounds in runs.items():
        every = [x["startup_s"] for rs in rounds for x in rs if x["exit"] == 0 and x["startup_s"]]
        failed[f"{n} x {compose}"] = sum(x["exit"] != 0 for rs in rounds for x in rs)
        objectives |= {x["objective"] for rs in rounds for x in rs if x["exit"] == 0}
        lost = f"{failed[f'{n} x {compose}']} of {n * len(rounds)}"
        if every:  # every run's start-up (s from the command to its first iteration line), over the rounds
            figures.append(figure(f"start-up, {n} run{'s' if n > 1 else ''} together, --compose {compose} ({lost} failed)",
                                  "s", every, note=f"{lost} runs failed"))
    single = RESULT.read_text(encoding="utf-8") if RESULT.exists() else "{}"
    command = (f"python bench/bench_sellar_startup.py --concurrent {args.concurrent} --compose {args.compose} "
               f"--repeat {args.repeat} --domain-id {args.domain_id}"
               + (" --append (after the calls whose rounds it kept)" if args.append else ""))
    write("bench_sellar_startup", figures, command=command, extra={"rows": json.loads(single).get("rows", []),  # the one-run part, kept
        "config": "config/leaf_nedc.yaml (recorded)",
        "rounds": {f"{n} x {c}": len(rounds) for (n, c), rounds in runs.items()}, "failed_runs": failed,
        "objectives": sorted(objectives), "raw": {f"{n}|{c}": rounds for (n, c), rounds in runs.items()}})
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--domain-id", type=int, default=22)
    ap.add_argument("--json", default=str(RESULT))
    ap.add_argument("--concurrent", default="", help="e.g. 1,4,8: runs started together on one domain")
    ap.add_argument("--compose", default="none,coordinator", help="with --concurrent: layouts to compare")
    ap.add_argument("--append", action="store_true", help="with --concurrent: keep the rounds already in the results file")
    args = ap.parse_args(argv)
    if args.concurrent:
        return concurrent(args)
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        cfgs = configs(tmp)
        runs: dict[tuple[str, str], list[dict]] = {}
        for _ in range(args.repeat):
            for name, path in cfgs.items():
                for transport in ("ros", "inprocess"):
                    runs.setdefault((name, transport), []).append(run_once(path, transport, args.domain_id, tmp))
    rows = []
    for (name, transport), rs in runs.items():
        walls = [r["wall_s"] for r in rs]
        rows.append({"config": name, "transport": transport, "times_s": walls,
                     "median_s": statistics.median(walls), "min_s": min(walls), "max_s": max(walls),
                     "optimisation_median_s": statistics.median(r["optimisation_s"] for r in rs),
                     "objective": rs[-1]["objective"], "iterations": rs[-1]["iterations"],
                     "feasible": rs[-1]["feasible"], "retried_total": sum(r["retried"] for r in rs),
                     "retry_warnings_total": sum(len(r["warnings"]) for r in rs)})
    # the one-run part: rows beside the --concurrent figures of the same file (kept)
    out = json.loads(Path(args.json).read_text(encoding="utf-8")) if Path(args.json).exists() else {}
    out.update({"bench": "bench_sellar_startup", "repeat": args.repeat, "host_cpus": os.cpu_count(), "rows": rows})
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(out, indent=2))
    print(f"start to result of `bev-mdo optimize CONFIG --json --no-record`, {args.repeat} runs each (interleaved)")
    print(f"{'config':16s} {'transport':10s} {'median s':>9s} {'min':>7s} {'max':>7s} {'opt. s':>8s} "
          f"{'retries':>7s} {'objective':>12s}")
    for r in rows:
        print(f"{r['config']:16s} {r['transport']:10s} {r['median_s']:9.2f} {r['min_s']:7.2f} {r['max_s']:7.2f} "
              f"{r['optimisation_median_s']:8.3f} {r['retried_total']:7d} {r['objective']:12.6f}")
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
