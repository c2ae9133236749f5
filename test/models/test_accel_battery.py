"""The battery limit on the 0-100 km/h run: the motors' total shaft power at most the pack's terminal power at
its 5C discharge limit (§3.5.3) x battery_to_shaft_efficiency, checked against a fine-step integration of
a force written out here, with no corner given (but a two-speed box's shift, where the force jumps)."""
import numpy as np
import pytest

from bev_mdo.models import acceleration as ac, topology_accel as ta
from bev_mdo.models.params import QUASI_STATIC_SPECS

D = {k: s.default for k, s in QUASI_STATIC_SPECS.items()}
V_END = 100 / 3.6


def pack_shaft_w(kwh, soc=0.9, c_rate=5.0, eta_bs=0.90):
    """The default Leaf-like cell (battery.py) by hand: 96 in series, 33.1 Ah, OCV 4.03 V and 4.0 mOhm at
    90 % SOC, nominal 24 kWh / (192 x 33.1 Ah); the terminal power (ocv - I R) I at 5C, x eta_bs."""
    assert soc == 0.9  # the table's own point: no interpolation to redo here
    n_par = kwh * 1e3 / (96 * 33.1 * (24000.0 / (192 * 33.1)))
    ocv, r, i = 96 * 4.03, 96 * 4.0e-3 / n_par, c_rate * 33.1 * n_par
    return (ocv - i * r) * i * eta_bs


def road(v, m):
    return 0.5 * D["air_density_kg_m3"] * D["drag_area_m2"] * v * v + D["rolling_resistance"] * m * D["gravity_m_s2"]


def motor_force(v, kw, t_peak, ratio, eta, w_lim, count=1):
    """One axle's envelope at the wheels (N): peak torque, then the motor's constant power, 0 past its limit."""
    w = v / D["wheel_radius_m"] * ratio
    tq = np.where(w <= w_lim, np.minimum(t_peak, kw * 1e3 / np.maximum(w, 1e-12)), 0.0)
    return count * tq * ratio * eta / D["wheel_radius_m"]


def fine_time(force, m, breaks=(), steps=2_000_000):
    """int_0^v_end M / F(v) dv by the midpoint rule on ``steps`` equal steps per piece between ``breaks``
    (a jump of the force only; no corner is given)."""
    edges = [0.0, *breaks, V_END]
    total = 0.0
    for a, b in zip(edges[:-1], edges[1:]):
        h = (b - a) / steps
        v = a + h * (np.arange(steps) + 0.5)
        f = force(v)
        assert np.all(f > 0)
        total += h * np.sum(m / f)
    return total


SM_SA_GRIP = 0.6 * D["gravity_m_s2"]  # mu 1 x the driven axle's 60 % share, per kg


def sm_sa_force(kw, ig, m, shaft_w, eta=D["gear_efficiency"]):
    w_lim = D["motor_speed_limit_rpm"] * np.pi / 30
    return lambda v: np.minimum(np.minimum(motor_force(v, kw, 3.5 * kw, ig, eta, w_lim), shaft_w * eta / v),
                                SM_SA_GRIP * m) - road(v, m)


def test_sm_sa_126_kw_on_22_kwh_is_held_to_the_pack_power():
    """126 kW on 22 kWh: the pack gives 88 kW to the shafts at 5C; the time is the fine-step one, slower than
    with the limit off (which is the model without it, as before)."""
    kw, ig, m, kwh = 126.0, 7.9, 1269.64 + 69 + 0.532 * 126 + 21.6 + 7.8 * 22, 22.0
    shaft = pack_shaft_w(kwh)
    assert 85e3 < shaft < 90e3 < kw * 1e3
    ref = fine_time(sm_sa_force(kw, ig, m, shaft), m)
    got = ac.accel_time_0_100_s(np.array([kw]), np.array([ig]), np.array([m]), battery_kwh=np.array([kwh]))[0]
    off = ac.accel_time_0_100_s(np.array([kw]), np.array([ig]), np.array([m]), {"battery_to_shaft_efficiency": 0.0},
                                battery_kwh=np.array([kwh]))[0]
    assert got == pytest.approx(ref, rel=1e-6)
    assert ta.accel_time_s("SM-SA", m, kw, ig, battery_kwh=kwh)[0] == pytest.approx(ref, rel=1e-6)
    assert got > off + 1.0
    assert off == ac.accel_time_0_100_s(np.array([kw]), np.array([ig]), np.array([m]))[0]
    assert off == pytest.approx(fine_time(sm_sa_force(kw, ig, m, np.inf), m), rel=1e-6)


def iwm_force(kw_f, kw_r, m, shaft_w):
    ss = D["iwm_speed_scale"]
    w_lim, tpk = D["motor_speed_limit_rpm"] * np.pi / 30 * ss, 3.5 / ss  # 700 N m per 38.2 kW unit motor
    drive = (lambda v: motor_force(v, kw_f, tpk * kw_f, 1.0, 1.0, w_lim, 2)
             + motor_force(v, kw_r, tpk * kw_r, 1.0, 1.0, w_lim, 2))
    return lambda v: np.minimum(np.minimum(drive(v), shaft_w / v), D["gravity_m_s2"] * m) - road(v, m)


def test_iwm_da_368_kw_on_21_6_kwh_is_held_to_the_pack_power():
    """The topology study's IWM-DA front design: four in-wheel motors of 92 kW (368 kW) on 21.6 kWh, whose pack
    gives 87 kW to the shafts at 5C: no longer 2.4 s to 100 km/h. The cap is on the sum of the four."""
    kw, m, kwh = 92.0, 1650.0, 21.6
    shaft = pack_shaft_w(kwh)
    assert 86e3 < shaft < 88e3
    ref = fine_time(iwm_force(kw, kw, m, shaft), m)
    got = ta.accel_time_s("IWM-DA", m, kw, motor_rear_kw=kw, battery_kwh=kwh)[0]
    off = ta.accel_time_s("IWM-DA", m, kw, motor_rear_kw=kw, battery_kwh=kwh,
                          params={"battery_to_shaft_efficiency": 0.0})[0]
    assert got == pytest.approx(ref, rel=1e-6)
    assert off == pytest.approx(fine_time(iwm_force(kw, kw, m, np.inf), m), rel=1e-6)
    assert off < 3.0 < 7.0 < got


def test_dm_da_unequal_axles_meet_the_pack_while_one_is_at_peak_torque():
    """Front 12:1 at constant power, rear 5:1 still at peak torque where the sum meets the pack's power: the
    corner of a mixed segment (T_r i_r eta / r_w + P_f eta / v = P_batt eta_bs eta / v)."""
    m, kwh, eta = 1800.0, 40.0, D["gear_efficiency"]
    shaft = pack_shaft_w(kwh)
    w_lim = D["motor_speed_limit_rpm"] * np.pi / 30
    drive = (lambda v: motor_force(v, 60.0, 3.5 * 60.0, 12.0, eta, w_lim) + motor_force(v, 150.0, 525.0, 5.0, eta, w_lim))
    r = D["wheel_radius_m"]
    v_cross = (shaft - 60e3) * eta / (525.0 * 5.0 * eta / r)
    assert 1000 / 3.5 * r / 12 < v_cross < 1000 / 3.5 * r / 5  # between the two base speeds
    ref = fine_time(lambda v: np.minimum(np.minimum(drive(v), shaft * eta / v), D["gravity_m_s2"] * m) - road(v, m), m)
    assert ta.accel_time_s("DM-DA", m, 60.0, 12.0, 150.0, 5.0, battery_kwh=kwh)[0] == pytest.approx(ref, rel=1e-6)


def test_two_speed_meets_the_pack_in_each_gear():
    """Two speeds, 12:1 then 3:1 from 36 km/h: the motor reaches the pack's power in first gear (the grip stops
    binding there), falls below it at the shift (its speed quarters: back at peak torque) and reaches it again in
    second gear."""
    kw, m, kwh, shift = 150.0, 1700.0, 22.0, 10.0
    eta = D["gear_efficiency"] - D["two_speed_efficiency_loss"]
    shaft = pack_shaft_w(kwh)
    w_lim = D["motor_speed_limit_rpm"] * np.pi / 30
    drive = (lambda v: np.where(v >= shift, motor_force(v, kw, 3.5 * kw, 3.0, eta, w_lim),
                                motor_force(v, kw, 3.5 * kw, 12.0, eta, w_lim)))
    r = D["wheel_radius_m"]
    assert shaft / (3.5 * kw * 12 / r) < shift < shaft / (3.5 * kw * 3 / r) < V_END  # a corner in each gear
    assert shaft * eta / shift < SM_SA_GRIP * m < 3.5 * kw * 12 * eta / r  # the grip binds in first gear only
    ref = fine_time(lambda v: np.minimum(np.minimum(drive(v), shaft * eta / v), SM_SA_GRIP * m) - road(v, m), m,
                    breaks=(shift,))
    p = {"gear_count": 2.0, "gear_ratio_2": 3.0, "shift_speed_m_s": shift}
    assert ta.accel_time_s("SM-SA", m, kw, 12.0, params=p, battery_kwh=kwh)[0] == pytest.approx(ref, rel=1e-6)


def test_a_design_within_the_pack_power_is_unchanged():
    """80 kW on 24 kWh (96 kW at the shafts): the same time as without the limit, to 1e-12, alone and in a batch
    beside a design that the limit holds; every topology."""
    kw, ig, m = np.array([80.0, 126.0]), np.array([7.9, 7.9]), np.array([1590.0, 1650.0])
    kwh = np.array([24.0, 22.0])
    on = ac.accel_time_0_100_s(kw, ig, m, battery_kwh=kwh)
    off = ac.accel_time_0_100_s(kw, ig, m)
    assert on[0] == pytest.approx(off[0], rel=1e-12) and on[1] > off[1] + 1.0
    assert ac.accel_time_0_100_s(kw[:1], ig[:1], m[:1], battery_kwh=kwh[:1])[0] == pytest.approx(off[0], rel=1e-12)
    cases = {"SM-SA": (kw, ig), "DM-DA": (kw / 2, ig, kw / 2, ig), "IWM-SA": (kw / 2,), "IWM-DA": (kw / 4, None, kw / 4)}
    for name, args in cases.items():
        on = ta.accel_time_s(name, m, *args, battery_kwh=kwh)
        off = ta.accel_time_s(name, m, *args)
        assert on[0] == pytest.approx(off[0], rel=1e-12) and on[1] > off[1] + 1.0, name
    # two speeds: 2-speed SM-SA
    p = {"gear_count": 2.0, "gear_ratio_2": 5.0, "shift_speed_m_s": 15.0}
    on, off = ta.accel_time_s("SM-SA", m, kw, ig, params=p, battery_kwh=kwh), ta.accel_time_s("SM-SA", m, kw, ig, params=p)
    assert on[0] == pytest.approx(off[0], rel=1e-12) and on[1] > off[1]


def test_the_pack_power_follows_the_battery_model():
    """P_batt at the discharge limit, at the run's initial SOC, never above ocv^2 / 4R (a high C-rate gives
    the pack's largest power), x battery_to_shaft_efficiency; 0 switches the limit off."""
    from bev_mdo.models.params import get_params

    p = get_params(None, ac.BATTERY_LIMIT_PARAMS)
    assert ac.battery_shaft_power_w(np.array([21.6]), p)[0] == pytest.approx(pack_shaft_w(21.6), rel=1e-12)
    low = ac.battery_shaft_power_w(np.array([21.6]), {**p, "initial_soc": 0.3})[0]
    assert low < pack_shaft_w(21.6)  # lower OCV at 30 % SOC
    n_par = 21.6 / 24.0 * 2
    ocv, r = 96 * 4.03, 96 * 4.0e-3 / n_par
    assert ac.battery_shaft_power_w(np.array([21.6]), {**p, "discharge_c_max": 100.0})[0] == pytest.approx(
        0.9 * ocv * ocv / (4 * r), rel=1e-12)
    assert ac.battery_shaft_power_w(np.array([21.6]), {**p, "battery_to_shaft_efficiency": 0.0}) == np.inf
    assert ac.battery_shaft_power_w(None, p) == np.inf
