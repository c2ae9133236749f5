"""Profile one composed-layout MDA round trip (issue 18): the composed node under `python -m cProfile`, the
coordinator timing `analyse` under cProfile; prints p50 and both profiles (tottime).

  . scripts/env.sh && flock /tmp/bev_bench.lock flock /tmp/bev_ros.lock python bench/profile_compose.py [DOMAIN] [N]
"""
import cProfile, os, pstats, signal, subprocess, sys, time
from pathlib import Path
REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
DOM = int(sys.argv[1]) if len(sys.argv) > 1 else 182
N = int(sys.argv[2]) if len(sys.argv) > 2 else 3000
os.environ["ROS_DOMAIN_ID"] = str(DOM); os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
import numpy as np, rclpy
from bev_mdo.testing import ros_env
from bev_mdo.config import load_config, run_settings
from bev_mdo.mdo.driver import build_formulation
from bev_mdo.ros.coordinator_node import CoordinatorNode, discipline_names
cfg_path = str(REPO / "config" / "leaf_nedc.yaml")
config = load_config(cfg_path); config = {**config, "ros": {**(config.get("ros") or {}), "signing": False}}
names = discipline_names(config)
run_id = f"prof{os.getpid()}"
env = ros_env(DOM)
argv = [sys.executable, "-m", "cProfile", "-o", "/tmp/bev_profile_compose_composed.prof", "-m", "bev_mdo.ros.run", "composed_node",
        "--ros-args", "-p", f"config:={cfg_path}", "-p", f"disciplines:={','.join(names)}", "-p", f"run_id:='{run_id}'"]
proc = subprocess.Popen(argv, env=env, stdout=subprocess.DEVNULL, stderr=open("/tmp/bev_profile_compose_composed.log", "w"))
ctx = rclpy.context.Context(); rclpy.init(context=ctx)
node = CoordinatorNode(config, run_id=run_id, context=ctx, node_name="prof_coord")
try:
    node.evaluator.wait_for_disciplines(names, 120.0); node.evaluator.warm_up(names)
    form = build_formulation(run_settings(config), node.evaluator)
    x = form.x0[None, :]
    for _ in range(200): form.analyse(x)
    lat = []
    prof = cProfile.Profile()
    prof.enable()
    for _ in range(N):
        t0 = time.perf_counter(); form.analyse(x); lat.append(time.perf_counter() - t0)
    prof.disable()
    print("p50 us", np.percentile(lat, 50) * 1e6, "p90", np.percentile(lat, 90) * 1e6, "flows", node.evaluator.flows,
          "load", os.getloadavg())
    prof.dump_stats("/tmp/bev_profile_compose_coord.prof")
finally:
    node.evaluator.close(); node.destroy_node(); rclpy.shutdown(context=ctx)
    proc.send_signal(signal.SIGINT); proc.wait(30)
for f in ("/tmp/bev_profile_compose_coord.prof", "/tmp/bev_profile_compose_composed.prof"):
    print("=====", f)
    pstats.Stats(f).sort_stats("tottime").print_stats(25)
