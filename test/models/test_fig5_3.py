"""Thesis Fig 5-3: second-order normalised sensitivities of the chapter-5 breakdown model.

Nominal point (Table 5-1 / ch.5 assumptions): M = 1590 kg, C_dA = 0.6412 m^2,
C_r = 0.007, eta_g = 0.97, eta_m = 0.85, regeneration 40 %. Expected matrices and
labels are copied from Fig 5-3 (a) NEDC and (b) Artemis; "~0" is taken as 0.
"""
import numpy as np
import pytest

from bev_mdo.mdo.sensitivity import sensitivities
from bev_mdo.models import breakdown, cycles

NAMES = ["drag_area_m2", "rolling_resistance", "vehicle_mass_kg",
         "gear_efficiency", "motor_efficiency", "regen_fraction"]
NOMINAL = [0.6412, 0.007, 1590.0, 0.97, 0.85, 0.40]

FIG_5_3A_NEDC = [
    [0, 0, 0, -0.36, -0.28, 0],
    [0, 0, 0.28, -0.27, -0.21, 0],
    [0, 0.28, 0, -0.88, -0.69, -0.13],
    [-0.36, -0.27, -0.88, 0, 0.91, -0.18],
    [-0.28, -0.21, -0.69, 0.91, 0, -0.14],
    [0, 0, -0.13, -0.18, -0.14, 0],
]
FIG_5_3B_ARTEMIS = [
    [0, 0, 0, -0.39, -0.31, 0],
    [0, 0, 0.20, -0.19, -0.15, 0],
    [0, 0.20, 0, -0.87, -0.69, -0.14],
    [-0.39, -0.19, -0.87, 0, 0.94, -0.2],
    [-0.31, -0.15, -0.69, 0.94, 0, -0.15],
    [0, 0, -0.14, -0.2, -0.15, 0],
]
# Upper triangle of the label table (same for both cycles), row by row.
FIG_5_3_LABELS = [
    ["NC", "NC", "NC", "MC", "MC", "NC"],
    ["NC", "MC", "MC", "MC", "NC"],
    ["NC", "VSC", "SC", "MC"],
    ["NC", "VSC", "MC"],
    ["NC", "MC"],
    ["NC"],
]


def _batch(resampled):
    def fun(X):
        params = {k: X[:, i] for i, k in enumerate(NAMES) if k != "vehicle_mass_kg"}
        return {"energy_wh_per_km": breakdown.energy_wh_per_km(resampled, params, X[:, 2], None, None)}
    return fun


@pytest.mark.parametrize("cycle, expected", [
    ("nedc", FIG_5_3A_NEDC), ("artemis_combined", FIG_5_3B_ARTEMIS)])
def test_fig_5_3_matrix_and_labels(cycle, expected):
    r = cycles.resample(cycles.load_cycle(cycle))
    s = sensitivities(_batch(r), dict(zip(NAMES, NOMINAL)), order=2)
    m = s.second["energy_wh_per_km"]
    np.testing.assert_allclose(m, m.T, atol=1e-12)
    np.testing.assert_allclose(m, np.array(expected), atol=0.05)
    labels = s.labels("energy_wh_per_km")
    for i, row in enumerate(FIG_5_3_LABELS):
        assert list(labels[i, i:]) == row, (NAMES[i], list(labels[i, i:]))
    assert np.max(s.second_error["energy_wh_per_km"]) < 1e-4


def test_nedc_complex_step_agrees_with_central():
    r = cycles.resample(cycles.nedc())
    point = dict(zip(NAMES, NOMINAL))
    c = sensitivities(_batch(r), point, method="complex")
    f = sensitivities(_batch(r), point, method="central")
    assert c.method == "complex"
    np.testing.assert_allclose(c.first["energy_wh_per_km"], f.first["energy_wh_per_km"], atol=1e-8)
    # Mass is the most sensitive body parameter, gear efficiency the most sensitive overall (ch.5.4).
    s = np.abs(c.first["energy_wh_per_km"])
    assert NAMES[int(np.argmax(s))] == "gear_efficiency"
    assert s[2] > max(s[0], s[1])
