"""Python calls per MDA (cProfile's call count, which the host's load does not change), beside the
coordinator without DDS (bench/profile_beside_nodds.py's wiring) and in process (issue 18).
No ROS lock needed (no participant is created).

  . scripts/env.sh && python bench/calls_per_mda.py     (HARNESS_REPO=<a copy of the tree> for another version)
"""
import cProfile, io, os, pstats, runpy, sys
from pathlib import Path

repo = os.environ.setdefault("HARNESS_REPO", str(Path(__file__).resolve().parents[1]))
sys.argv = ["profile_beside_nodds.py", "20"]
g = runpy.run_path(repo + "/bench/profile_beside_nodds.py", run_name="harness")
form, ref, x = g["form"], g["ref"], g["x"]
N = 500
for f, label in ((form, "beside (no DDS)"), (ref, "in process")):
    for _ in range(50):
        f.analyse(x)
    pr = cProfile.Profile()
    pr.enable()
    for _ in range(N):
        f.analyse(x)
    pr.disable()
    print(f"{label}: {pstats.Stats(pr, stream=io.StringIO()).total_calls / N:.0f} Python calls per MDA")
