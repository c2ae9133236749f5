"""scripts/pair_noise_floor.py (docs/validation.md "Ceiling of the pairs"): couples are what pairs leave
out, and the perfect model's expected figures match a simulation of measurement scatter."""
import importlib.util
from pathlib import Path

import numpy as np

from bev_mdo.models import fleet as fl
from bev_mdo.models import pairs as pr

ROOT = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("pair_noise_floor", ROOT / "scripts" / "pair_noise_floor.py")
pnf = importlib.util.module_from_spec(spec)
spec.loader.exec_module(pnf)


def test_couples_are_the_rows_of_one_model_line_that_pairs_leave_out():
    fleet = fl.read_fleet()
    line = fleet.model_line()
    cps = pnf.couples(fleet)
    pairs = set(pr.find_pairs(line, fleet.drive, fleet.rated_power_kw, fleet.test_mass_kg, ~fleet.outlier))
    same_line = {(a, b) for a in range(len(fleet)) for b in range(a + 1, len(fleet)) if line[a] == line[b]}
    assert len(cps) == 33 and pairs.isdisjoint(cps) and pairs | set(cps) == same_line


def test_the_perfect_models_expected_figures_match_simulated_scatter():
    """A model with no error, scored against measurements with scatter: its mean slope and mean
    absolute difference over many draws are what perfect_model expects (slope attenuated)."""
    rng = np.random.default_rng(7)
    true = rng.normal(0.0, 12.0, 105)
    sigma = 3.5
    slopes, mads = [], []
    for _ in range(4000):
        x = true + rng.normal(0.0, sigma, true.size)
        slopes.append(np.dot(x, true) / np.dot(x, x))
        mads.append(np.mean(np.abs(true - x)))
    x = true + rng.normal(0.0, sigma, true.size)
    expect = pnf.perfect_model(x, rng.normal(0.0, sigma, 20_000))
    assert abs(np.mean(slopes) - expect["slope"]) < 0.02 and np.mean(slopes) < 0.95
    assert abs(np.mean(mads) - expect["mean_abs_diff_points"]) < 0.05
    assert abs(expect["scatter_rms_points"] - sigma) < 0.05
