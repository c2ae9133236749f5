import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from bev_mdo.models.cycles import Resampled, nedc, resample
from bev_mdo.models.flat import energy_wh_per_km, energy_wh_per_km_direct, traction_force_n

P = dict(air_density_kg_m3=1.25, gravity_m_s2=9.81, drag_area_m2=0.6412, rolling_resistance=0.007,
         wheel_radius_m=0.316, gear_efficiency=0.97, motor_constant_nm_a=0.4, motor_resistance_ohm=0.02,
         motor_inductance_h=0.001, regen_fraction=0.4)


def tiny():
    # 3 samples, 1 s apart: accelerating, cruising, braking
    return Resampled("tiny", 1.0, np.array([0.0, 1.0, 2.0]), np.array([10.0, 20.0, 10.0]),
                     np.array([2.0, 0.0, -3.0]), np.array([0.5, 0.0, -1.0]))


def hand_energy(M, ig, p):
    r = tiny()
    total = 0.0
    for v, a, j in zip(r.speed_m_s, r.accel_m_s2, r.jerk_m_s3):
        F = 0.5 * p["air_density_kg_m3"] * p["drag_area_m2"] * v * v + p["rolling_resistance"] * M * 9.81 + M * a
        e = 1 / p["gear_efficiency"] if F >= 0 else p["gear_efficiency"]
        k = p["wheel_radius_m"] / (p["motor_constant_nm_a"] * ig)
        I = k * e * F
        dI = k * e * (p["air_density_kg_m3"] * p["drag_area_m2"] * v * a + M * j)
        V = p["motor_inductance_h"] * dI + p["motor_resistance_ohm"] * I + p["motor_constant_nm_a"] * ig * v / p["wheel_radius_m"]
        w = 1.0 if F >= 0 else p["regen_fraction"]
        total += w * I * V * 1.0
    return total / 3.6 / (40.0 * 1.0)  # J -> Wh per km: /3600 * 1000 m/km over 40 m


def test_traction_force_hand_value():
    # 0.5*1.25*0.6*10*10 + 0.01*1000*9.81 + 1000*1.5
    assert traction_force_n(10.0, 1.5, 1000.0, 0.6, 0.01) == pytest.approx(37.5 + 98.1 + 1500.0)
    assert traction_force_n(0.0, 0.0, 1000.0, 0.6, 0.01) == 0.0  # no rolling resistance at rest


@pytest.mark.parametrize("fn", [energy_wh_per_km, energy_wh_per_km_direct])
def test_energy_equations_on_three_samples(fn):
    for M, ig in ((1500.0, 8.0), (1200.0, 3.0)):
        assert fn(tiny(), P, np.array([M]), np.array([ig]))[0] == pytest.approx(hand_energy(M, ig, P), rel=1e-12)


def test_moments_equal_direct_sum_on_nedc():
    rng = np.random.default_rng(1)
    m, g = rng.uniform(900, 3000, 500), rng.uniform(1, 12, 500)
    for interp in ("pchip", "spline"):
        r = resample(nedc(), 1.0, interp) if interp == "pchip" else resample(nedc(), 0.5, interp, smoothing=5.0)
        np.testing.assert_allclose(energy_wh_per_km(r, P, m, g), energy_wh_per_km_direct(r, P, m, g), rtol=1e-10)


def test_per_point_parameters_match_scalar_calls():
    r = resample(nedc())
    m, g = np.array([1500.0, 1600.0]), np.array([7.0, 9.0])
    cda = np.array([0.5, 0.8])
    regen = np.array([0.0, 1.0])
    vec = energy_wh_per_km(r, {**P, "drag_area_m2": cda, "regen_fraction": regen}, m, g)
    for i in range(2):
        one = energy_wh_per_km(r, {**P, "drag_area_m2": cda[i], "regen_fraction": regen[i]}, m[i:i + 1], g[i:i + 1])
        assert vec[i] == pytest.approx(one[0], rel=1e-12)


def test_vectorised_equals_loop():
    r = resample(nedc())
    m, g = np.linspace(1300, 1900, 7), np.linspace(2, 11, 7)
    vec = energy_wh_per_km(r, P, m, g)
    loop = [energy_wh_per_km(r, P, m[i:i + 1], g[i:i + 1])[0] for i in range(7)]
    np.testing.assert_allclose(vec, loop, rtol=1e-13)


def test_regeneration_lowers_energy():
    r = resample(nedc())
    e = [energy_wh_per_km(r, {**P, "regen_fraction": x}, np.array([1590.0]), np.array([8.0]))[0] for x in (0, 0.4, 1)]
    assert e[0] > e[1] > e[2]


@settings(max_examples=40, deadline=None)
@given(st.floats(1000, 2500), st.floats(2, 11), st.floats(1.001, 1.5),
       st.sampled_from(["vehicle_mass_kg", "drag_area_m2", "rolling_resistance"]))
def test_energy_rises_with_mass_cda_cr(m, g, factor, which):
    r = resample(nedc())
    base = energy_wh_per_km(r, P, np.array([m]), np.array([g]))[0]
    if which == "vehicle_mass_kg":
        up = energy_wh_per_km(r, P, np.array([m * factor]), np.array([g]))[0]
    else:
        up = energy_wh_per_km(r, {**P, which: P[which] * factor}, np.array([m]), np.array([g]))[0]
    assert up > base


@pytest.mark.parametrize("name,value", [("drag_area_m2", -0.1), ("regen_fraction", 1.5),
                                        ("motor_resistance_ohm", np.nan), ("wheel_radius_m", np.inf)])
def test_bad_parameter_names_itself(name, value):
    with pytest.raises(ValueError, match=name):
        energy_wh_per_km(resample(nedc()), {**P, name: value}, np.array([1500.0]), np.array([8.0]))


@pytest.mark.parametrize("m,g,name", [(-1.0, 8.0, "vehicle_mass_kg"), (1500.0, np.nan, "gear_ratio")])
def test_bad_design_names_itself(m, g, name):
    with pytest.raises(ValueError, match=name):
        energy_wh_per_km(resample(nedc()), P, np.array([m]), np.array([g]))
