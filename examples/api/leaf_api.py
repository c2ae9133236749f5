"""The Python API on the default problem: the Nissan Leaf on the NEDC, asked for 250 km of range.

    python examples/api/leaf_api.py            # a table of the optimum
    python examples/api/leaf_api.py --json     # the optimum as JSON (the tests compare it with the CLI's)

The same run on the command line: ``bev-mdo optimize config/leaf_nedc.yaml --constraint "range_km>=250"
--transport inprocess``. docs/api.md is the API's manual.
"""
import json
import sys
from pathlib import Path

from bev_mdo import Study

CONFIG = Path(__file__).resolve().parents[2] / "config" / "leaf_nedc.yaml"

study = Study(CONFIG).constrain("range_km", lower=250)  # like --constraint "range_km>=250"
result = study.optimize(transport="inprocess")  # no ROS; the default, "ros", runs the discipline nodes
if "--json" in sys.argv:
    print(json.dumps({"x": result.x, "objective": result.objective, "verdict": result.verdict}))
else:
    print(f"verdict: {result.verdict}")
    for row in result.rows():
        print(f"{row['name']:<24}{row['value']:>12.6g}  {row['role']}")
    print("active constraints: " + ", ".join(c["name"] for c in result.first_order["active_constraints"]))
