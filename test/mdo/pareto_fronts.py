"""Checks of a computed Pareto front against a problem's analytic one (examples/pareto/), shared by the
in-process and the ROS tests.

Distances are measured in objective space normalised by the analytic front's extent (each objective
to [0, 1] over the front). With P designs spread along a front of normalised length L ~ 1.2-1.5, the
spacing is about L / P; the tolerances are stated for P = 40 and follow from that, not from one run:

* every design lies on the front: the largest distance to it (GD max) < 0.05 and the mean < 0.01
  (NSGA-II with 40 x 60-250 generations reaches 2e-3..3e-2 and 3e-4..4e-3 over seeds 1-5);
* the designs cover it: the mean distance of the analytic front to the nearest design (IGD) < 0.025,
  about twice the spacing's quarter, and no analytic point farther than 0.15 from a design (no hole of
  more than a few spacings; the extremes are reached). Seeds 1-5 give IGD 1.0e-2..1.4e-2 and 0.035..0.081.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from bev_mdo.mdo.pareto import non_dominated

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "pareto"
# problem -> (generations at a population of 40, {constraint: (lower, upper)})
RUNS = {"zdt1": (250, {}), "srn": (60, {"c1": (None, 225.0), "c2": (None, 0.0)}),
        "tnk": (100, {"c1": (0.0, None), "c2": (None, 0.5)})}
POP = 40
GD_MAX, GD_MEAN, IGD, IGD_MAX = 0.05, 0.01, 0.025, 0.15


def analytic_front(problem: str) -> np.ndarray:
    sys.path.insert(0, str(EXAMPLES))
    try:
        import pareto_problems
    finally:
        sys.path.remove(str(EXAMPLES))
    return getattr(pareto_problems, problem.upper()).analytic_front()


def distances(F: np.ndarray, A: np.ndarray) -> dict[str, float]:
    """GD max / mean (designs to the front) and IGD mean / max (front to the designs), normalised."""
    lo, span = A.min(axis=0), np.ptp(A, axis=0)
    f, a = (F - lo) / span, (A - lo) / span
    d = np.sqrt(((f[:, None, :] - a[None, :, :]) ** 2).sum(axis=2))
    return {"gd_max": float(d.min(axis=1).max()), "gd_mean": float(d.min(axis=1).mean()),
            "igd": float(d.min(axis=0).mean()), "igd_max": float(d.min(axis=0).max())}


def check_front(problem: str, front_json: Path) -> dict[str, float]:
    """The front of ``front.json``: feasible, non-dominated, on and across the analytic front."""
    doc = json.loads(front_json.read_text())
    assert [o["name"] for o in doc["objectives"]] == ["f1", "f2"]
    rows = doc["front"]
    assert len(rows) >= POP // 2, len(rows)
    F = np.array([[r["f1"], r["f2"]] for r in rows])
    assert non_dominated(F).all()
    for name, (lo, hi) in RUNS[problem][1].items():
        v = np.array([r[name] for r in rows])
        assert (lo is None or np.all(v >= lo)) and (hi is None or np.all(v <= hi)), name
    m = distances(F, analytic_front(problem))
    assert m["gd_max"] < GD_MAX and m["gd_mean"] < GD_MEAN, m
    assert m["igd"] < IGD and m["igd_max"] < IGD_MAX, m
    return m
