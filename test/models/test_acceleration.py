import numpy as np
import pytest
from hypothesis import given, strategies as st

from bev_mdo.models.acceleration import accel_time_0_100_s, accel_time_s

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
