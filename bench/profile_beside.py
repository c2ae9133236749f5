"""Profile one MDA with every discipline composed into the coordinator's process (``--compose
coordinator``, composed.Beside; issue 18): p50 without a profiler, then the same MDAs under cProfile,
with the time grouped by what it is spent on (signing off and on). Everything runs in this process.

  . scripts/env.sh && flock /tmp/bev_bench.lock flock /tmp/bev_ros.lock \
      python bench/profile_beside.py [--domain 171] [--n 3000] [--signing off,on] [--json FILE] [--top 25]
"""
from __future__ import annotations

import argparse
import cProfile
import json
import os
import pstats
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

CDR = {"encode_request", "encode_result", "decode_request", "decode_result", "decode", "signed", "signed_bytes",
       "unsigned_request", "unsigned_result", "_request_cdr", "_result_cdr", "_head", "_named_bytes", "_text_at",
       "_cdr_text", "_cdr_texts", "_put_errors", "_plain_texts", "_string", "_strings", "_header", "_ids", "_named",
       "_plain_strings", "values"}
# (group, predicate on (file, function name)) in order: the first that matches takes a function's own time
GROUPS = [
    ("sign/verify (HMAC)", lambda f, n: f.endswith("auth.py") or "hmac" in f or f.endswith("_hashlib") or "hash" in n
     or "digest" in n),
    ("CDR encode/decode", lambda f, n: f.endswith("wire.py") and n in CDR),
    ("message objects, batch <-> columns (wire.py: Result(), batch, from_named_array, ...)",
     lambda f, n: f.endswith("wire.py")),
    ("discipline compute (models/)", lambda f, n: "/models/" in f),
    ("run_discipline / flow rule (mdo/discipline, mdo/flow)", lambda f, n: f.endswith("mdo/discipline.py")
     or f.endswith("mdo/flow.py")),
    ("engine: MDA / formulation (mdo/ others)", lambda f, n: "/mdo/" in f),
    ("coordinator ledger / evaluator (ros/evaluator, ledger)", lambda f, n: f.endswith("ros/evaluator.py")
     or f.endswith("ledger.py")),
    ("discipline node handlers (ros/discipline_node, composed)", lambda f, n: f.endswith("discipline_node.py")
     or f.endswith("composed.py") or f.endswith("binding.py")),
    ("rcl / DDS (rclpy, wait, publish, graph counts, stamp)", lambda f, n: "rclpy" in f or "fastwait" in f
     or "get_subscription_count" in n or "publish" in n or f.endswith("common.py") or "rclpy" in n),
    ("numpy", lambda f, n: "numpy" in f or n.startswith("<method '") and ("ndarray" in n or "numpy" in n)
     or "<built-in method numpy" in n),
]


def group_of(func) -> str:
    f, _, n = func
    for name, pred in GROUPS:
        try:
            if pred(f, n):
                return name
        except Exception:  # noqa: BLE001
            pass
    return "other Python (builtins, json, time, ...)"


def one(signing: bool, domain: int, n: int, top: int, tmp: Path) -> dict:
    import numpy as np
    import rclpy

    from bev_mdo.config import load_config, run_settings
    from bev_mdo.mdo.driver import build_formulation
    from bev_mdo.ros.auth import new_key_file
    from bev_mdo.ros.composed import Beside
    from bev_mdo.ros.coordinator_node import CoordinatorNode, discipline_names

    config = load_config(str(REPO / "config" / "leaf_nedc.yaml"))
    ros = {**(config.get("ros") or {}), "signing": signing}
    if signing:
        ros["sign_key_file"] = new_key_file(tmp, f"k{time.monotonic_ns()}.key")
    config = {**config, "ros": ros}
    names = discipline_names(config)
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=domain)
    run_id = f"profbeside{os.getpid()}"
    beside = Beside(config, names, ctx, run_id=run_id)
    node = CoordinatorNode(config, run_id=run_id, context=ctx, node_name="prof_beside_coordinator")
    beside.attach(node.evaluator)
    try:
        ev = node.evaluator
        ev.wait_for_disciplines(names, 120.0)
        ev.warm_up(names)
        form = build_formulation(run_settings(config), ev)
        x = form.x0[None, :]
        for _ in range(200):
            form.analyse(x)
        lat = []
        for _ in range(n):
            t0 = time.perf_counter()
            form.analyse(x)
            lat.append(time.perf_counter() - t0)
        p50 = float(np.percentile(lat, 50) * 1e6)
        prof = cProfile.Profile()
        t0 = time.perf_counter()
        prof.enable()
        for _ in range(n):
            form.analyse(x)
        prof.disable()
        prof.dump_stats(f"/tmp/bev_profile_beside_{'signed' if signing else 'unsigned'}.prof")
        wall_prof = (time.perf_counter() - t0) / n * 1e6
        st = pstats.Stats(prof)
        total = sum(v[2] for v in st.stats.values())
        groups: dict[str, float] = {}
        for func, (cc, nc, tt, ct, callers) in st.stats.items():
            g = group_of(func)
            groups[g] = groups.get(g, 0.0) + tt
        share = {g: round(t / total, 3) for g, t in sorted(groups.items(), key=lambda kv: -kv[1])}
        ncalls = {}
        for func, (cc, nc, tt, ct, callers) in st.stats.items():
            if func[2] in ("encode_request", "encode_result", "decode_request", "decode_result", "_mac",
                           "verify_request", "verify_result", "sign_request", "sign_result", "publish",
                           "get_subscription_count", "run_discipline", "_on_result", "_on_request",
                           "_on_mda_request", "_on_source_result", "wait", "take_ready", "stamp", "batch",
                           "from_named_array", "_for_me", "match", "settle", "on_local", "_flow"):
                ncalls[f"{Path(func[0]).name}:{func[2]}"] = {"per_mda": round(nc / n, 2),
                                                             "own_us_per_mda": round(tt / n * 1e6, 1),
                                                             "cum_us_per_mda": round(ct / n * 1e6, 1)}
        print(f"== signing {'on' if signing else 'off'}: p50 {p50:.0f} us (no profiler); "
              f"{wall_prof:.0f} us per MDA under cProfile; flows {ev.flows}; dropped {dict(ev.dropped)}", flush=True)
        for g, s in share.items():
            print(f"   {s * 100:5.1f} %  {g}")
        st.sort_stats("tottime").print_stats(top)
        return {"signing": signing, "p50_us": p50, "p90_us": float(np.percentile(lat, 90) * 1e6),
                "us_per_mda_under_cprofile": wall_prof, "own_time_share": share, "calls": ncalls,
                "flows": ev.flows, "dropped": dict(ev.dropped)}
    finally:
        beside.close()
        node.evaluator.close()
        node.destroy_node()
        rclpy.shutdown(context=ctx)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--domain", type=int, default=171)
    ap.add_argument("--n", type=int, default=3000)
    ap.add_argument("--signing", default="off,on")
    ap.add_argument("--top", type=int, default=25)
    ap.add_argument("--json", default="")
    ap.add_argument("--label", default="", help="what code was measured (in the rendered title)")
    args = ap.parse_args()
    os.environ["ROS_DOMAIN_ID"] = str(args.domain)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    load0 = os.getloadavg()[0]
    out = {"bench": "profile_beside: one MDA (leaf_nedc, one design), six disciplines beside the coordinator",
           "command": " ".join(["python bench/profile_beside.py", *sys.argv[1:]]),
           "date_utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime()), "n": args.n, "runs": []}
    with tempfile.TemporaryDirectory() as tmp:
        for s in args.signing.split(","):
            out["runs"].append(one(s.strip() == "on", args.domain, args.n, args.top, Path(tmp)))
    out["load_average_1min"] = {"before": load0, "after": os.getloadavg()[0]}
    if args.label:
        out["bench"] += f" ({args.label})"
    out["host"] = {"cpus": os.cpu_count(), "load_average_1min": round(os.getloadavg()[0], 2),
                   "python": sys.version.split()[0]}
    # rendered into docs/performance.md (scripts/render_bench.py): one profiled run each, so one value
    out["figures"] = [{"what": f"MDA p50 without the profiler, signing {'on' if r['signing'] else 'off'}"
                               + f" (cProfile: {r['us_per_mda_under_cprofile']:.0f} us per MDA)",
                       "unit": "us", "median": r["p50_us"], "min": r["p50_us"], "max": r["p50_us"],
                       "runs": [r["p50_us"]]} for r in out["runs"]]
    print("load average", out["load_average_1min"])
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2))
        print("wrote", args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
