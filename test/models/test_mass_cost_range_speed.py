import numpy as np
import pytest
from hypothesis import given, strategies as st

from bev_mdo.models import cost, mass, motor_speed, range as rng


def test_ch7_mass_equations():
    # eq 7-19..7-21 by hand: 1000 + 50 + (0.532*100 + 21.6) + 7.8*30
    m = mass.vehicle_mass_ch7_kg(np.array([100.0]), np.array([30.0]), glider_kg=1000.0, load_kg=50.0)
    assert m[0] == pytest.approx(1000 + 50 + 74.8 + 234.0)


def test_ch7_nominal_mass_is_1590():
    assert mass.vehicle_mass_kg(np.array([80.0]), np.array([24.0]), {})[0] == pytest.approx(1590.0)


def test_compounding_rule_and_table_3_1():
    m = mass.kerb_mass_compounding_kg(np.array([80.0, 100.0]), np.array([24.0, 24.0]))
    assert m[0] == pytest.approx(1521.0)
    assert m[1] == pytest.approx(1521.0 + 1.6 * 0.532 * 20)  # text: the difference times 1.6
    # Table 3-1's 1689 kg is the *whole* new powertrain times 1.6 on top of the glider:
    assert (1521 - 64.16 - 187.4) + (74.8 + 187.4) * 1.6 == pytest.approx(1689, abs=0.1)


def test_mass_model_choice_rejected():
    with pytest.raises(ValueError, match="mass_model"):
        mass.vehicle_mass_kg(np.array([80.0]), np.array([24.0]), {}, "ch8")


def test_cost_equations():
    # motor 16*50+385; cell 11.1*4+221.1 = 265.5 $/kWh; pack (265.5+13)*10+680
    assert cost.powertrain_cost_usd(np.array([50.0]), np.array([10.0]))[0] == pytest.approx(1185 + 2785 + 680)


def test_range_and_inverse():
    assert rng.range_km(np.array([24.0]), np.array([120.0]))[0] == pytest.approx(200.0)
    assert rng.battery_kwh_for_range(170.0, np.array([100.0]))[0] == pytest.approx(17.0)


@given(st.floats(1, 100), st.floats(1.001, 2), st.floats(50, 300))
def test_range_rises_with_battery_at_fixed_mass(b, f, e):
    assert rng.range_km(np.array([b * f]), np.array([e]))[0] > rng.range_km(np.array([b]), np.array([e]))[0]


def test_motor_speed_eq_7_29():
    v = 120 / 3.6
    assert motor_speed.motor_speed_max_rad_s(np.array([8.0]), v, 0.316)[0] == pytest.approx(8 * v / 0.316)
    assert motor_speed.motor_speed_max_rad_s(np.array([8.0]), v, 0.15)[0] > 1000  # Table 7-5 literal radius


@pytest.mark.parametrize("call,name", [
    (lambda: mass.motor_mass_kg(np.array([-5.0])), "motor_kw"),
    (lambda: mass.battery_mass_kg(np.array([np.inf])), "battery_kwh"),
    (lambda: rng.range_km(np.array([24.0]), np.array([0.0])), "energy_wh_per_km"),
    (lambda: cost.powertrain_cost_usd(np.array([80.0]), np.array([24.0]), -1.0), "power_to_energy_ratio"),
    (lambda: motor_speed.motor_speed_max_rad_s(np.array([8.0]), 30.0, 0.0), "wheel_radius_m"),
])
def test_bad_values_name_parameter_and_range(call, name):
    with pytest.raises(ValueError, match=rf"{name} must be .*\[") as e:
        call()
    assert "\n" not in str(e.value)
