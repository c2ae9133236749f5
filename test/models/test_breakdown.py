"""Chapter-5 analytic breakdown: Table 5-1, hand-computed terms, smoothness, vectorisation."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from bev_mdo.models import breakdown as bd
from bev_mdo.models.cycles import DriveCycle, load_cycle, resample

ROWS = ("aerodynamic", "rolling_resistance", "inertia", "regenerative_recovery",
        "transmission_loss", "motor_loss", "total")
# Thesis Table 5-1 (kWh/100 km), M = 1590 kg, C_dA 0.6412, C_r 0.007, eta_g 0.97, eta_m 0.85.
TABLE_NEDC = {
    0.0: (4.03, 3.05, 4.95, 0.00, 0.36, 1.86, 14.25),
    0.4: (4.03, 3.05, 4.95, -1.98, 0.42, 2.16, 12.63),
    0.5: (4.03, 3.05, 4.95, -2.47, 0.44, 2.24, 12.23),
    0.8: (4.03, 3.05, 4.95, -3.96, 0.48, 2.47, 11.02),
    1.0: (4.03, 3.05, 4.95, -4.95, 0.51, 2.62, 10.21),
}
TABLE_ARTEMIS = {
    0.0: (6.42, 3.05, 7.91, 0.00, 0.52, 2.68, 20.58),
    0.4: (6.42, 3.05, 7.91, -2.37, 0.59, 3.05, 18.64),  # computed at 30 %, see test below
    0.5: (6.42, 3.05, 7.91, -3.95, 0.64, 3.30, 17.35),
    0.8: (6.42, 3.05, 7.91, -6.33, 0.71, 3.66, 15.42),
    1.0: (6.42, 3.05, 7.91, -7.91, 0.76, 3.91, 14.13),
}
NOMINAL = {"drag_area_m2": 0.6412, "rolling_resistance": 0.007, "gear_efficiency": 0.97,
           "motor_efficiency": 0.85}


def _close(ours, thesis):
    # 1 % of the printed value, widened by half its last printed digit (values are rounded
    # to 0.01): 0.44 stands for [0.435, 0.445). Only the small loss rows need the widening;
    # rows >= 1 kWh/100 km and the totals are also checked at a strict 1 % below.
    return abs(ours - thesis) <= 0.01 * abs(thesis) + 0.005


@pytest.fixture(scope="module")
def nedc():
    return resample(load_cycle("nedc"), 1.0)


@pytest.fixture(scope="module")
def artemis():
    return resample(load_cycle("artemis_combined"), 1.0)


@pytest.mark.parametrize("regen", sorted(TABLE_NEDC))
def test_table_5_1_nedc(nedc, regen):
    out = bd.energy_breakdown(nedc, dict(NOMINAL, regen_fraction=regen), 1590.0)
    for row, thesis in zip(ROWS, TABLE_NEDC[regen]):
        ours = float(out[row][0])
        assert _close(ours, thesis), (row, ours, thesis)
        if abs(thesis) >= 1.0:
            assert abs(ours - thesis) <= 0.01 * abs(thesis), (row, ours, thesis)
    # Table 5-1 lists the battery losses as "Negligible" and leaves them out of the total;
    # eqs 5-19/5-20 in SI give 0.11-0.12 kWh/100 km, below the smallest listed row.
    assert 0 < out["battery_discharge_loss"][0] < out["transmission_loss"][0]
    assert 0 <= out["battery_charge_loss"][0] < out["transmission_loss"][0]
    parts = sum(float(out[r][0]) for r in ROWS[:-1])
    assert out["total"][0] == pytest.approx(parts, rel=1e-12)


@pytest.mark.parametrize("regen", [0.0, 0.5, 0.8, 1.0])
def test_table_5_1_artemis(artemis, regen):
    # The packaged urban segment is 993 s (thesis 920 s); the columns still agree within 1 %.
    out = bd.energy_breakdown(artemis, dict(NOMINAL, regen_fraction=regen), 1590.0)
    for row, thesis in zip(ROWS, TABLE_ARTEMIS[regen]):
        assert _close(float(out[row][0]), thesis), (row, float(out[row][0]), thesis)


def test_table_5_1_artemis_40_column_is_30_percent(artemis):
    # The thesis' Artemis "40 %" column has recovery -2.37 = 0.30 x 7.91 and its losses and
    # total follow from that; at 30 % every row agrees, at 40 % the recovery is 0.4 x inertia.
    out30 = bd.energy_breakdown(artemis, dict(NOMINAL, regen_fraction=0.3), 1590.0)
    for row, thesis in zip(ROWS, TABLE_ARTEMIS[0.4]):
        assert _close(float(out30[row][0]), thesis), row
    out40 = bd.energy_breakdown(artemis, dict(NOMINAL, regen_fraction=0.4), 1590.0)
    assert out40["regenerative_recovery"][0] == pytest.approx(-0.4 * out40["inertia"][0])


def test_terms_by_hand_on_triangle():
    # 0 -> 10 m/s in 10 s, back to 0 in 10 s, linear: distance 100 m.
    t = np.arange(21.0)
    v = np.r_[np.arange(11.0), np.arange(9.0, -1.0, -1.0)]
    cyc = DriveCycle("tri", t, v)
    m, cda, cr, rho, g = 1000.0, 0.5, 0.01, 1.25, 9.81
    p = {"drag_area_m2": cda, "rolling_resistance": cr, "gear_efficiency": 0.9,
         "motor_efficiency": 0.8, "regen_fraction": 0.5, "battery_loss_weight": 1.0}
    out = bd.energy_breakdown(cyc, p, m)
    k = 1e5 / 3.6e6
    vbar = np.r_[np.arange(0.5, 10.0), np.arange(9.5, 0.0, -1.0)]
    aero = 0.5 * rho * cda * np.sum(vbar ** 3) / 100.0
    inertia = 0.5 * m * 10.0 ** 2 / 100.0  # kinetic energy at 10 m/s, per metre
    roll = cr * m * g
    regen = 0.5 * inertia
    gear = (aero + roll + inertia + regen) * 0.1
    motor = (aero + roll + inertia + regen + gear) * 0.2
    i_d = (aero + roll + inertia + gear + motor) * 100.0 / (20.0 * 345.0)
    i_c = regen * 100.0 / (20.0 * 345.0)
    batt = (i_d ** 2 * 0.192 + i_c ** 2 * 0.216) * 20.0 / 100.0
    assert out["aerodynamic"][0] == pytest.approx(aero * k)
    assert out["inertia"][0] == pytest.approx(inertia * k)
    assert out["rolling_resistance"][0] == pytest.approx(roll * k)
    assert out["transmission_loss"][0] == pytest.approx(gear * k)
    assert out["motor_loss"][0] == pytest.approx(motor * k)
    assert out["total"][0] == pytest.approx((aero + roll + inertia - regen + gear + motor + batt) * k)
    wh = bd.energy_wh_per_km(cyc, dict(p, battery_loss_weight=0.0), m, 8.0, 80.0)
    assert wh[0] == pytest.approx((aero + roll + inertia - regen + gear + motor) / 3.6)


def test_vectorised_equals_loop(nedc):
    rng = np.random.default_rng(1)
    m = rng.uniform(1000, 2500, 7)
    cda = rng.uniform(0.4, 1.0, 7)
    eta = rng.uniform(0.8, 0.99, 7)
    batch = bd.energy_wh_per_km(nedc, {"drag_area_m2": cda, "gear_efficiency": eta}, m, 8.0, 80.0)
    loop = [bd.energy_wh_per_km(nedc, {"drag_area_m2": cda[i], "gear_efficiency": eta[i]}, m[i], 8.0, 80.0)[0]
            for i in range(7)]
    assert batch.shape == (7,)
    np.testing.assert_allclose(batch, loop, rtol=1e-13)


def test_complex_step_matches_analytic_derivative(nedc):
    # d(total)/d(r) = inertia * (-1 + (1-eta_g) + (1-eta_g)(1-eta_m) + (1-eta_m)), by hand from
    # eqs 5-16..5-18 with battery_loss_weight = 0; also against a central difference.
    h = 1e-30
    p = dict(NOMINAL, regen_fraction=0.4 + 1j * h)
    d_cs = bd.energy_wh_per_km(nedc, p, 1590.0, 8.0, 80.0).imag / h
    e = lambda r: bd.energy_wh_per_km(nedc, dict(NOMINAL, regen_fraction=r), 1590.0, 8.0, 80.0)[0]
    d_fd = (e(0.4 + 1e-6) - e(0.4 - 1e-6)) / 2e-6
    inertia_wh_km = bd.energy_breakdown(nedc, NOMINAL, 1590.0)["inertia"][0] * 10
    d_hand = inertia_wh_km * (-1 + 0.03 + 0.03 * 0.15 + 0.15)  # -I + gear + motor shares
    assert d_cs[0] == pytest.approx(d_fd, rel=1e-7)
    assert d_cs[0] == pytest.approx(d_hand, rel=1e-12)
    dm = bd.energy_wh_per_km(nedc, NOMINAL, np.array([1590.0 + 1j * h]), 8.0, 80.0).imag / h
    assert dm[0] > 0


@settings(max_examples=40, deadline=None)
@given(m=st.floats(600, 3000), dm=st.floats(1, 500), regen=st.floats(0, 1))
def test_energy_rises_with_mass(nedc, m, dm, regen):
    e = bd.energy_wh_per_km(nedc, {"regen_fraction": regen}, np.array([m, m + dm]), 8.0, 80.0)
    assert e[1] > e[0]


@pytest.mark.parametrize("name,value", [("drag_area_m2", -0.1), ("gear_efficiency", 1.2),
                                        ("regen_fraction", np.nan), ("motor_efficiency", np.inf)])
def test_bad_parameter_names_range(nedc, name, value):
    with pytest.raises(ValueError, match=rf"{name} must be in \["):
        bd.energy_breakdown(nedc, {name: value}, 1590.0)


def test_bad_mass_and_shape(nedc):
    with pytest.raises(ValueError, match=r"vehicle_mass_kg must be in \["):
        bd.energy_breakdown(nedc, {}, -5.0)
    with pytest.raises(ValueError, match=r"arrays of different lengths: vehicle_mass_kg \(2,\), drag_area_m2 \(3,\)"):
        bd.energy_breakdown(nedc, {"drag_area_m2": np.ones(3) * 0.6}, np.ones(2) * 1500)


def test_parameter_array_with_scalar_mass_broadcasts(nedc):
    e = bd.energy_wh_per_km(nedc, {"regen_fraction": np.array([0.0, 0.4])}, 1590.0, 8.0, 80.0)
    assert e.shape == (2,)
    assert e[0] > e[1]
