"""Cost of signing (on by default) beside unsigned, on this host.

    . scripts/env.sh && flock /tmp/bev_ros.lock python bench/bench_signing.py [--rounds 5] [--n 300]

Two suites of the six Leaf discipline nodes, one unsigned (domain 64), one with a key file
(domain 65, what `bev-mdo optimize` does with its per-run key), and one coordinator per suite
in this process. Rounds alternate unsigned / signed so host noise hits both alike; each round
measures
  - the latency of one multidisciplinary evaluation of one design point (p50 of --n MDAs), and
  - batched throughput: designs per second for batches of 1 000 and 10 000 points (median of 3).
Reported per mode: median and range (min, max) over the rounds, and the signed/unsigned ratio
of the medians. Also the CPU cost of signing + verifying one request and its result (no ROS).
Writes bench/results/signing.json.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
DOMAINS = {"unsigned": 64, "signed": 65}
BATCHES = (1_000, 10_000)


def _summary(xs: list[float]) -> dict:
    return {"median": statistics.median(xs), "min": min(xs), "max": max(xs), "runs": len(xs)}


def cpu_sign_verify(n: int = 2000) -> dict:
    """CPU only, for a request and its result (one point, and a 10 000-point batch):
    - ``sign_verify_*``: sign + verify the message objects, as the older API did;
    - ``send_receive_*``: the whole hop, signed and unsigned: encode (and sign) the bytes that are
      published, decode them, verify. Works with the older API (sign in place, then
      encode) and after (the signer returns the bytes it signed), so one file measures both."""
    import secrets

    from bev_mdo import protocol
    from bev_mdo.protocol.signing import Signer
    from bev_mdo.ros.common import stamp

    out = {}
    for points in (1, 10_000):
        s = Signer(secrets.token_bytes(32))
        req = protocol.request("bench", 1, "energy")
        req.inputs = protocol.batch({k: np.ones(points) for k in ("vehicle_mass_kg", "gear_ratio", "motor_kw")})
        res = protocol.result()
        res.run_id, res.discipline = "bench", "energy"
        res.point_ok = np.ones(points, bool)
        res.outputs = protocol.batch({"energy_wh_per_km": np.ones(points)})
        reps = n if points == 1 else max(20, n // 50)
        t0 = time.perf_counter()
        for i in range(reps):
            req.evaluation_id = res.evaluation_id = i
            stamp(req.header)
            stamp(res.header)
            s.sign_request(req)
            s.sign_result(res)
            assert s.verify_request(req) is None and s.verify_result(res) is None
        out[f"sign_verify_request_and_result_{points}_points_us"] = (time.perf_counter() - t0) / reps * 1e6
        for signer in (None, Signer(secrets.token_bytes(32))):
            t0 = time.perf_counter()
            for i in range(reps):
                req.evaluation_id = res.evaluation_id = i
                stamp(req.header)
                stamp(res.header)
                for m, encode, decode in ((req, protocol.encode_request, protocol.decode_request),
                                          (res, protocol.encode_result, protocol.decode_result)):
                    if signer is None:
                        data = encode(m)
                    else:
                        data = (signer.sign_request if m is req else signer.sign_result)(m)
                        if data is None:  # the older API: signed in place, encoded by the caller
                            data = encode(m)
                    got = decode(data)
                    if signer is not None:
                        assert (signer.verify_request if m is req else signer.verify_result)(got) is None
            mode = "unsigned" if signer is None else "signed"
            out[f"send_receive_request_and_result_{points}_points_{mode}_us"] = (time.perf_counter() - t0) / reps * 1e6
    return out


def cpu_only(rounds: int) -> dict:
    """``cpu_sign_verify`` ``rounds`` times: median and range of each figure."""
    runs = [cpu_sign_verify() for _ in range(rounds)]
    return {k: _summary([r[k] for r in runs]) for k in runs[0]}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--n", type=int, default=300, help="MDAs per latency figure")
    ap.add_argument("--json", default=str(REPO / "bench" / "results" / "signing.json"))
    ap.add_argument("--domains", default="64,65", metavar="UNSIGNED,SIGNED", help="the two suites' ROS domains")
    ap.add_argument("--cpu-only", action="store_true", help="only the CPU figures (no ROS), --rounds times")
    args = ap.parse_args()
    if args.cpu_only:
        figures = {"cpu": cpu_only(args.rounds), "load_average_1min": os.getloadavg()[0]}
        print(json.dumps(figures, indent=2))
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(figures, indent=2) + "\n")
        return 0
    DOMAINS.update(zip(("unsigned", "signed"), (int(d) for d in args.domains.split(","))))
    load = [os.getloadavg()[0]]
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    import rclpy

    from bev_mdo.config import load_config, run_settings
    from bev_mdo.mdo.driver import build_formulation
    from bev_mdo.protocol.signing import new_key_file
    from bev_mdo.ros.coordinator_node import CoordinatorNode, discipline_names
    from bev_mdo.launcher import Launcher
    from bev_mdo.processes import discipline_argv
    from bev_mdo.testing import ros_env

    tmp = Path(tempfile.mkdtemp(prefix="bench_signing_"))
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    paths = {}
    for mode in DOMAINS:
        r = dict(raw)
        r["ros"] = {"discovery_wait_s": 60.0, "signing": False}
        if mode == "signed":
            r["ros"]["sign_key_file"] = new_key_file(tmp)
        paths[mode] = tmp / f"{mode}.yaml"
        paths[mode].write_text(yaml.safe_dump(r, sort_keys=False))
    launchers, ctxs, nodes, forms = {}, {}, {}, {}
    figures: dict = {"host_cpus": os.cpu_count(), "cpu": cpu_sign_verify()}
    per_round = {m: {"mda_one_point_p50_us": [], **{f"batch_{b}_designs_per_s": [] for b in BATCHES}}
                 for m in DOMAINS}
    try:
        for mode, domain in DOMAINS.items():
            config = load_config(paths[mode])
            launchers[mode] = la = Launcher(ros_env(domain))
            for name in discipline_names(config):
                la.add(name, discipline_argv(name, str(paths[mode])))
            ctxs[mode] = ctx = rclpy.context.Context()
            rclpy.init(context=ctx, domain_id=domain)
            nodes[mode] = node = CoordinatorNode(config, context=ctx, node_name=f"bench_signing_{mode}")
            assert (node.evaluator.signer is not None) == (mode == "signed")
            node.evaluator.wait_for_disciplines(discipline_names(config), 60.0)
            forms[mode] = form = build_formulation(run_settings(config), node.evaluator)
            for _ in range(30):
                form.analyse(form.x0[None, :])
        rng = np.random.default_rng(0)
        for _ in range(args.rounds):
            for mode in DOMAINS:
                form = forms[mode]
                x = form.x0[None, :]
                lat = []
                for _ in range(args.n):
                    t0 = time.perf_counter()
                    form.analyse(x)
                    lat.append(time.perf_counter() - t0)
                per_round[mode]["mda_one_point_p50_us"].append(float(np.percentile(lat, 50)) * 1e6)
                for b in BATCHES:
                    X = form.lower + (form.upper - form.lower) * rng.random((b, len(form.lower)))
                    reps = []
                    for _ in range(3):
                        t0 = time.perf_counter()
                        res = form.analyse(X)
                        reps.append(time.perf_counter() - t0)
                    assert res.ok.any()
                    per_round[mode][f"batch_{b}_designs_per_s"].append(b / statistics.median(reps))
        for mode in DOMAINS:
            d = dict(nodes[mode].evaluator.dropped)
            assert not any(d.get(k) for k in ("unsigned", "forged", "expired", "replayed")), d
        figures["modes"] = {m: {k: _summary(v) for k, v in per_round[m].items()} for m in DOMAINS}
        figures["signed_over_unsigned"] = {
            k: figures["modes"]["signed"][k]["median"] / figures["modes"]["unsigned"][k]["median"]
            for k in per_round["signed"]}
        load.append(os.getloadavg()[0])
        figures["load_average_1min"] = {"start": load[0], "end": load[1]}
    finally:
        for mode in list(nodes):
            nodes[mode].evaluator.close()
            nodes[mode].destroy_node()
        for ctx in ctxs.values():
            rclpy.shutdown(context=ctx)
        for la in launchers.values():
            la.stop()
    print(json.dumps(figures, indent=2))
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(figures, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
