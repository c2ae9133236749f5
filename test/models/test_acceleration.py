import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, strategies as st
from scipy.integrate import quad

from bev_mdo.models import topology as tp, topology_accel as ta
from bev_mdo.models.acceleration import accel_time_0_100_s, accel_time_s
from bev_mdo.models.params import VEHICLE_SPECS, load_parameter_set

NO_ROAD = dict(drag_area_m2=0.05, rolling_resistance=0.0, air_density_kg_m3=0.5, wheel_radius_m=0.3,
               gear_efficiency=1.0, motor_torque_per_kw=3.5, motor_speed_limit_rpm=30000.0)


def test_constant_torque_then_constant_power_by_hand():
    p = {**NO_ROAD}
    P_kw, ig, M, v_end = 80.0, 8.0, 1500.0, 100 / 3.6
    F0 = 3.5 * P_kw * ig / 0.3                     # constant-torque wheel force
    v_b = (1000 / 3.5) * 0.3 / ig                  # base speed at the wheel
    t_hand = M * v_b / F0 + M * (v_end ** 2 - v_b ** 2) / (2 * P_kw * 1000)
    t = accel_time_s(np.array([P_kw]), np.array([ig]), np.array([M]), p, v_end)[0]
    # residual drag (0.5*0.5*0.05*v^2 <= 9.7 N against >= 2880 N of drive force) only slows it,
    # by less than 9.7/2880 = 0.34 %
    assert t_hand < t < t_hand * (1 + 9.7 / 2880)


def test_speed_limit_makes_target_unreachable():
    t = accel_time_0_100_s(np.array([80.0, 80.0]), np.array([8.0, 8.0]), np.array([1590.0, 1590.0]),
                           {"wheel_radius_m": np.array([0.15, 0.316])})
    assert np.isinf(t[0]) and 5 < t[1] < 15


@given(st.floats(40, 119), st.floats(1.01, 1.5), st.floats(4, 11), st.floats(1200, 2000))
def test_time_falls_with_motor_power(p, f, g, m):
    a = accel_time_0_100_s(np.array([p, min(p * f, 1000)]), np.array([g, g]), np.array([m, m]))
    assert a[1] < a[0]


def test_vectorised_equals_loop():
    P, g, m = np.array([40.0, 80, 120]), np.array([5.0, 8, 10]), np.array([1500.0, 1590, 1700])
    vec = accel_time_0_100_s(P, g, m)
    np.testing.assert_allclose(vec, [accel_time_0_100_s(P[i:i + 1], g[i:i + 1], m[i:i + 1])[0] for i in range(3)])


def test_bad_values():
    with pytest.raises(ValueError, match="motor_torque_per_kw"):
        accel_time_0_100_s(np.array([80.0]), np.array([8.0]), np.array([1590.0]), {"motor_torque_per_kw": 0.0})


# ----------------------------------------------------------------------------- tyre grip


V_END = 100 / 3.6
DEF = {k: s.default for k, s in VEHICLE_SPECS.items()}
REFERENCE = Path(__file__).resolve().parents[1] / "data" / "accel_thesis_reference.json"


def grip_bound_time(m, share, mu=1.0, v_end=V_END):
    """Rest to v_end at F = mu g share M - C_r M g - 1/2 rho CdA v^2 throughout: int M / (a - k v^2) dv."""
    a = mu * DEF["gravity_m_s2"] * share * m - DEF["rolling_resistance"] * m * DEF["gravity_m_s2"]
    k = 0.5 * DEF["air_density_kg_m3"] * DEF["drag_area_m2"]
    return m / np.sqrt(a * k) * np.arctanh(v_end * np.sqrt(k / a))


def fine_time(force, m, corners, v_end=V_END):
    """int_0^v_end M / F(v) dv with quad between the given corners (scalar force)."""
    edges = sorted({0.0, v_end, *[c for c in corners if 0 < c < v_end]})
    return sum(quad(lambda v: m / force(v), a, b, epsabs=0, epsrel=1e-13, limit=200)[0]
               for a, b in zip(edges[:-1], edges[1:]))


def road(v, m):
    return (0.5 * DEF["air_density_kg_m3"] * DEF["drag_area_m2"] * v * v
            + DEF["rolling_resistance"] * m * DEF["gravity_m_s2"])


def test_1000_kw_in_1500_kg_is_grip_bound():
    """It took 0.70 s; one driven axle of 60 % of the weight at mu = 1 cannot beat v_end / (0.6 g)."""
    t = accel_time_0_100_s(np.array([1000.0]), np.array([8.0]), np.array([1500.0]))[0]
    assert t > V_END / (0.6 * DEF["gravity_m_s2"])
    assert t == pytest.approx(grip_bound_time(1500.0, 0.6), rel=1e-12)
    two = accel_time_0_100_s(np.array([1000.0]), np.array([8.0]), np.array([1500.0]), {"driven_axles": 2.0})[0]
    assert two == pytest.approx(grip_bound_time(1500.0, 1.0), rel=1e-12)


@pytest.mark.parametrize("topology, share, rear", [("SM-SA", 0.6, {}), ("DM-DA", 1.0, {"motor_rear_kw": 1000.0}),
                                                   ("IWM-SA", 0.6, {}), ("IWM-DA", 1.0, {"motor_rear_kw": 1000.0})])
def test_every_topology_is_grip_bound_with_its_driven_axles(topology, share, rear):
    t = tp.get_topology(topology)
    gears = {"gear_ratio": 8.0, **({"gear_ratio_rear": 8.0} if t.two_axles else {})} if t.geared else {}
    got = ta.accel_time_s(topology, 1500.0, 1000.0, **gears, **rear)[0]
    assert got == pytest.approx(grip_bound_time(1500.0, share), rel=1e-12)
    mu = ta.accel_time_s(topology, 1500.0, 1000.0, **gears, **rear, params={"tyre_grip_coefficient": 0.8,
                                                                            "driven_axle_load_share": 0.5})[0]
    assert mu == pytest.approx(grip_bound_time(1500.0, share if share == 1.0 else 0.5, mu=0.8), rel=1e-12)


def test_grip_binding_part_of_the_way_is_integrated_exactly():
    """150 kW, 9:1, 1500 kg: grip-bound up to v = P eta / F_grip (16.4 m/s), then constant power; the corner
    is a segment edge, so Gauss-Legendre is exact there as on the base speed."""
    kw, ig, m = 150.0, 9.0, 1500.0
    grip, eta = 0.6 * DEF["gravity_m_s2"] * m, DEF["gear_efficiency"]
    v_grip = kw * 1e3 * eta / grip
    ref = fine_time(lambda v: min(grip, kw * 1e3 * eta / max(v, 1e-9)) - road(v, m), m, [v_grip])
    assert accel_time_0_100_s(np.array([kw]), np.array([ig]), np.array([m]))[0] == pytest.approx(ref, rel=1e-12)
    assert ta.accel_time_s("SM-SA", m, kw, ig)[0] == pytest.approx(ref, rel=1e-12)


def test_two_speed_grip_binding_only_in_second_gear_is_integrated_exactly():
    """First gear 3:1 (no grip limit in it), second 9:1 from 30 km/h: the grip binds only after the shift
    (the force rises there), up to a corner in second gear."""
    kw, m, eta = 200.0, 1500.0, DEF["gear_efficiency"] - 0.02
    p = {"gear_count": 2.0, "gear_ratio_2": 9.0, "shift_speed_m_s": 30 / 3.6}
    grip, r = 0.6 * DEF["gravity_m_s2"] * m, DEF["wheel_radius_m"]

    def drive(v):
        ig = 9.0 if v >= p["shift_speed_m_s"] else 3.0
        return min(3.5 * kw, kw * 1e3 / max(v / r * ig, 1e-9)) * ig * eta / r
    assert drive(1.0) < grip < drive(p["shift_speed_m_s"])
    corners = [p["shift_speed_m_s"], 1000 / 3.5 * r / 3.0, kw * 1e3 * eta / grip]
    ref = fine_time(lambda v: min(drive(v), grip) - road(v, m), m, corners)
    assert ta.accel_time_s("SM-SA", m, kw, 3.0, params=p)[0] == pytest.approx(ref, rel=1e-12)


def test_dm_da_with_unequal_axles_is_integrated_exactly():
    """The grip stops binding while the rear axle (5:1) is still at peak torque and the front (12:1) at
    constant power: F = T_r i_r eta / r_w + P_f eta / v = grip there."""
    m, r, eta = 1800.0, DEF["wheel_radius_m"], DEF["gear_efficiency"]
    grip = DEF["gravity_m_s2"] * m  # two driven axles: all the weight

    def axle(v, kw, ig):
        return min(3.5 * kw, kw * 1e3 / max(v / r * ig, 1e-9)) * ig * eta / r
    drive = (lambda v: axle(v, 120.0, 12.0) + axle(v, 150.0, 5.0))
    v_grip = 120e3 * eta / (grip - 3.5 * 150.0 * 5.0 * eta / r)
    bases = [1000 / 3.5 * r / 12.0, 1000 / 3.5 * r / 5.0]
    assert bases[0] < v_grip < bases[1] and drive(v_grip) == pytest.approx(grip, rel=1e-12)
    ref = fine_time(lambda v: min(drive(v), grip) - road(v, m), m, [*bases, v_grip])
    assert ta.accel_time_s("DM-DA", m, 120.0, 12.0, 150.0, 5.0)[0] == pytest.approx(ref, rel=1e-12)


def test_the_time_has_the_right_derivative_where_the_grip_binds():
    """The acceleration discipline has no analytic partials: the optimiser differences the time. Where the
    grip binds to v_g = P eta / F_grip, dt/dP = -int_vg^v_end M eta / v / (P eta / v - road)^2 dv (the
    corner term cancels: the force is continuous there)."""
    kw, ig, m, eta = 150.0, 9.0, 1500.0, DEF["gear_efficiency"]
    v_grip = kw * 1e3 * eta / (0.6 * DEF["gravity_m_s2"] * m)
    exact = -quad(lambda v: m * 1e3 * eta / v / (kw * 1e3 * eta / v - road(v, m)) ** 2, v_grip, V_END,
                  epsabs=0, epsrel=1e-12)[0]
    h = 1e-3
    for f in (lambda p: accel_time_0_100_s(np.array([p]), np.array([ig]), np.array([m]))[0],
              lambda p: ta.accel_time_s("SM-SA", m, p, ig)[0]):
        assert (f(kw + h) - f(kw - h)) / (2 * h) == pytest.approx(exact, rel=1e-6)


def designs(n, ranges):
    """n deterministic designs in the given (lower, upper) ranges (Kronecker sequence, no random stream)."""
    alpha = np.mod(np.sqrt(np.array([2.0, 3.0, 5.0, 7.0, 11.0])), 1.0)[:len(ranges)]
    x = np.mod(np.arange(1, n + 1, dtype=float)[:, None] * alpha, 1.0)
    return {k: lo + (hi - lo) * x[:, j] for j, (k, (lo, hi)) in enumerate(ranges.items())}


RANGES = {"motor_kw": (10.0, 1000.0), "gear_ratio": (2.0, 12.5), "vehicle_mass_kg": (500.0, 5000.0),
          "motor_rear_kw": (10.0, 1000.0), "gear_ratio_rear": (2.0, 12.5)}
SM_SA = ("motor_kw", "gear_ratio", "vehicle_mass_kg")
CASES = {"SM-SA": SM_SA, "SM-SA two-speed": SM_SA, "DM-DA": tuple(RANGES), "IWM-SA": ("motor_kw", "vehicle_mass_kg"),
         "IWM-DA": ("motor_kw", "vehicle_mass_kg", "motor_rear_kw")}


@pytest.mark.parametrize("case", ["flat SM-SA", *CASES])
def test_the_thesis_parameter_set_gives_the_model_without_grip(case):
    """parameter_set thesis (tyre_grip_coefficient 0, battery_to_shaft_efficiency 0) reproduces the times
    before the grip and battery limits on 200 designs up to 1000 kW on an 18 kWh pack (most of which the
    default grip limit slows down, and the default battery limit more)."""
    want = np.array([np.inf if x is None else x for x in json.loads(REFERENCE.read_text())[case]])
    th = load_parameter_set("thesis")
    names = CASES.get(case, CASES["SM-SA"])
    d = designs(200, {k: RANGES[k] for k in names})
    kwh = np.full(200, 18.0)
    if case == "flat SM-SA":
        args = (d["motor_kw"], d["gear_ratio"], d["vehicle_mass_kg"])
        got = accel_time_0_100_s(*args, th, battery_kwh=kwh)
        default = accel_time_0_100_s(*args)
        battery = accel_time_0_100_s(*args, battery_kwh=kwh)
    else:
        extra = {"gear_count": 2.0} if "two-speed" in case else {}
        args = (case.split()[0], d["vehicle_mass_kg"], d["motor_kw"], d.get("gear_ratio"), d.get("motor_rear_kw"),
                d.get("gear_ratio_rear"))
        got = ta.accel_time_s(*args, params={**th, **extra}, battery_kwh=kwh)
        default = ta.accel_time_s(*args, params=extra)
        battery = ta.accel_time_s(*args, params=extra, battery_kwh=kwh)
    np.testing.assert_array_equal(np.isinf(got), np.isinf(want))
    np.testing.assert_allclose(got[np.isfinite(want)], want[np.isfinite(want)], rtol=1e-12)
    assert np.sum(default > want * (1 + 1e-9)) > 100  # the set does switch the grip limit off
    assert np.sum(battery > default * (1 + 1e-9)) > 100  # and the battery limit


@pytest.mark.parametrize("name, value", [("tyre_grip_coefficient", -0.1), ("tyre_grip_coefficient", 2.5),
                                         ("driven_axle_load_share", 0.9), ("driven_axles", 1.5)])
def test_bad_grip_parameters_are_one_line(name, value):
    with pytest.raises(ValueError, match=f"^{name} must be"):
        accel_time_0_100_s(np.array([80.0]), np.array([8.0]), np.array([1590.0]), {name: value})
    with pytest.raises(ValueError, match=f"^{name} must be"):
        ta.accel_time_s("SM-SA", 1590.0, 80.0, 8.0, params={name: value})


def test_a_design_that_cannot_reach_100_km_h_gets_the_continuation_value_of_its_top_speed():
    """Continuation (module doc): 10 000 s + 100 s per km/h of top speed short of 100 km/h; finite, and
    falling as the design moves toward reaching 100 km/h (more power, a lower ratio)."""
    from bev_mdo.models.acceleration import NOT_REACHED_S, not_reached_note

    kw, ig = np.array([5.0, 6.0, 80.0, 80.0, 80.0]), np.array([8.0, 8.0, 14.0, 13.0, 8.0])
    m = np.full(5, 1550.0)
    t = accel_time_0_100_s(kw, ig, m, continuation=True)
    plain = accel_time_0_100_s(kw, ig, m)
    assert np.all(np.isinf(plain[:4])) and np.all(np.isfinite(t)) and np.all(t[:4] >= NOT_REACHED_S)
    assert t[4] == plain[4]  # a design that reaches 100 km/h: the same time, to the bit
    assert t[1] < t[0] and t[3] < t[2]  # more power; a lower ratio
    # over the speed limit at 14:1: the top speed is where the motor reaches 10 500 rpm
    v_lim_km_h = 10500 * np.pi / 30 * 0.316 / 14 * 3.6
    assert t[2] == pytest.approx(NOT_REACHED_S + 100.0 * (100.0 - v_lim_km_h), rel=1e-12)
    assert f"top speed {v_lim_km_h:.1f} km/h" in not_reached_note(t[2])
    assert not_reached_note(t[4]) is None


def test_the_top_speed_of_a_weak_motor_is_where_its_power_meets_the_road_load():
    from bev_mdo.models.acceleration import NOT_REACHED_S
    from bev_mdo.models import road_load as rl

    t = accel_time_0_100_s(np.array([5.0]), np.array([8.0]), np.array([1550.0]), continuation=True)[0]
    top = (100.0 - (t - NOT_REACHED_S) / 100.0) / 3.6
    from bev_mdo.models.acceleration import ACCEL_PARAMS
    from bev_mdo.models.params import get_params

    p = {**get_params(None, ACCEL_PARAMS), **rl.checked(None)}
    drive = 5000.0 * p["gear_efficiency"] / top  # constant power: 8:1 puts the base speed far below
    assert drive == pytest.approx(rl.road_load_n(p, np.array([top]), 1550.0)[0], rel=1e-9)


@pytest.mark.parametrize("topology, args", [
    ("SM-SA", (np.array([5.0, 80.0, 80.0]), np.array([8.0, 14.0, 8.0]))),
    ("DM-DA", (np.array([40.0]), np.array([7.9]), np.array([40.0]), np.array([13.0]))),
    ("IWM-SA", (np.array([5.0]),))])
def test_the_topology_model_gives_the_same_continuation(topology, args):
    from bev_mdo.models.acceleration import NOT_REACHED_S

    m = np.full(args[0].shape, 1550.0)
    t = ta.accel_time_s(topology, m, *args, continuation=True)
    plain = ta.accel_time_s(topology, m, *args)
    assert np.all(np.isfinite(t)) and np.array_equal(np.isinf(plain), t >= NOT_REACHED_S)
    assert np.array_equal(t[np.isfinite(plain)], plain[np.isfinite(plain)])
    if topology == "SM-SA":
        np.testing.assert_allclose(t, accel_time_0_100_s(*args, m, continuation=True), rtol=1e-12)
