"""scripts/fleet_ceiling.py (docs/validation.md "Ceiling of the level: any model of these columns"): its work features split the wheel work
consistently, and its linear and ridge scorers recover a relation that is there."""
import importlib.util
from pathlib import Path

import numpy as np
import pytest

from bev_mdo.models import fleet as fl

ROOT = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("fleet_ceiling", ROOT / "scripts" / "fleet_ceiling.py")
fc = importlib.util.module_from_spec(spec)
spec.loader.exec_module(fc)


@pytest.fixture(scope="module")
def fleet_feats():
    fleet = fl.read_fleet()
    return fleet, fc.work_features(fleet, fl.resampled_cycles())


def test_positive_work_is_the_sum_of_its_parts(fleet_feats):
    _, f = fleet_feats
    np.testing.assert_allclose(f["WA"] + f["WB"] + f["WC"] + f["WI"], f["Wp"], rtol=1e-12)
    assert np.all(f["Wp"] > f["Wn"]) and np.all(f["Wn"] > 0)


def test_linear_cv_recovers_an_exact_relation(fleet_feats):
    fleet, f = fleet_feats
    y = 1.3 * f["Wp"] - 0.7 * f["Wn"] + 250.0 * f["T"]
    groups = np.tile(np.arange(len(fleet)) % 5, 2)
    err, b = fc.linear_cv(f, y, ("Wp", "Wn", "T"), groups)
    assert err < 1e-9
    np.testing.assert_allclose(b, [1.3, -0.7, 250.0], rtol=1e-9)
    err_wrong, _ = fc.linear_cv(f, y, ("Wp",), groups)
    assert err_wrong > 1.0


def test_nested_ridge_finds_a_linear_signal_and_not_noise():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(120, 4))
    groups = np.arange(120) % 12
    t = 0.05 * X[:, 0] - 0.03 * X[:, 2]
    pred = fc.ridge_nested(X[groups != 0], t[groups != 0], X[groups == 0], groups[groups != 0])
    np.testing.assert_allclose(pred, t[groups == 0], atol=2e-3)
    noise = rng.normal(scale=0.05, size=120)
    pred = fc.ridge_nested(X[groups != 0], noise[groups != 0], X[groups == 0], groups[groups != 0])
    assert np.std(pred) < 0.5 * np.std(noise)
