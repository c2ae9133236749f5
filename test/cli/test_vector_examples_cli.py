"""The vector-variable examples with analytic partials through the `bev-mdo optimize` command in
process (the CLI wraps the evaluator for timeouts and error naming; the partials must pass through)."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from bev_mdo.testing import REPO


@pytest.mark.parametrize("example, objective, reference, tol", [
    ("golinski.yaml", "weight", 2994.4711, 0.01),   # Golinski's speed reducer (docs/vector-variables.md)
])
def test_a_vector_example_with_partials_runs_through_the_cli(tmp_path, example, objective, reference, tol):
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    p = subprocess.run([sys.executable, "-m", "bev_mdo", "optimize", str(REPO / "examples" / example),
                        "--transport", "inprocess", "--json", "--quiet"],
                       capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300)
    assert p.returncode == 0, p.stderr[-3000:]
    out = json.loads(p.stdout)
    assert out["feasible"]
    assert out["outputs"][objective] == pytest.approx(reference, abs=tol)
    # analytic partials: one analysis per iteration, no FD stencil (the end-point check's two central-difference
    # stencils, which confirm the assembled derivatives, are its own cost)
    assert out["mda_evaluations"] - out["first_order"]["cost"]["points"] < 30
    assert out["first_order"]["derivatives_confirmed"]
