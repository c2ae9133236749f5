"""The shared input checks of models/common.py at work in every model that uses them: arrays of
different lengths and complex values are one-line ValueErrors naming the input (numpy's broadcast
message named neither; a complex value lost its imaginary part with a ComplexWarning)."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from bev_mdo.models import acceleration, breakdown, chain, cost, flat, mass, quasi_static as qs, range as range_model
from bev_mdo.models.cycles import nedc, resample

R = resample(nedc(), 1.0)
TWO, THREE = np.array([80.0, 90.0]), np.array([24.0, 25.0, 26.0])
M3 = np.array([1500.0, 1600.0, 1700.0])

MISMATCHED = {
    "flat": (lambda: flat.energy_wh_per_km(R, {}, M3, np.array([8.0, 9.0])), r"vehicle_mass_kg \(3,\), gear_ratio \(2,\)"),
    "flat direct": (lambda: flat.energy_wh_per_km_direct(R, {}, M3, np.array([8.0, 9.0])),
                    r"vehicle_mass_kg \(3,\), gear_ratio \(2,\)"),
    "flat parameter": (lambda: flat.energy_wh_per_km(R, {"regen_fraction": np.array([0.3, 0.4])}, M3, 8.0),
                       r"vehicle_mass_kg \(3,\), regen_fraction \(2,\)"),
    "range": (lambda: range_model.range_km(np.array([24.0, 30.0]), np.array([100.0, 110.0, 120.0])),
              r"battery_kwh \(2,\), energy_wh_per_km \(3,\)"),
    "battery for range": (lambda: range_model.battery_kwh_for_range(np.array([200.0, 300.0]), M3 / 10),
                          r"range_target_km \(2,\), energy_wh_per_km \(3,\)"),
    "range usable fraction": (lambda: range_model.range_km(THREE, 100.0, np.array([0.9, 0.8])),
                              r"battery_kwh \(3,\), battery_usable_fraction \(2,\)"),
    "cost": (lambda: cost.powertrain_cost_usd(TWO, THREE), r"motor_kw \(2,\), battery_kwh \(3,\)"),
    "pack cost": (lambda: cost.pack_cost_usd(THREE, np.array([4.0, 5.0])), r"battery_kwh \(3,\), power_to_energy_ratio \(2,\)"),
    "mass": (lambda: mass.vehicle_mass_ch7_kg(TWO, THREE), r"motor_kw \(2,\), battery_kwh \(3,\)"),
    "mass parameter": (lambda: mass.vehicle_mass_kg(TWO, 24.0, {"glider_kg": M3}), r"motor_kw \(2,\), glider_kg \(3,\)"),
    "compounding": (lambda: mass.vehicle_mass_kg(TWO, THREE, {}, "compounding"), r"motor_kw \(2,\), battery_kwh \(3,\)"),
    "acceleration": (lambda: acceleration.accel_time_0_100_s(TWO, np.array([8.0, 9.0, 10.0]), np.array([1500.0, 1600.0])),
                     r"motor_kw \(2,\), gear_ratio \(3,\), vehicle_mass_kg \(2,\)"),
    "acceleration parameter": (lambda: acceleration.accel_time_0_100_s(TWO, 8.0, 1590.0, {"drag_area_m2": THREE / 40}),
                               r"motor_kw \(2,\), drag_area_m2 \(3,\)"),
    "quasi_static": (lambda: qs.energy_wh_per_km(R, {}, M3, np.array([8.0, 9.0]), 80.0),
                     r"vehicle_mass_kg \(3,\), gear_ratio \(2,\)"),
    "breakdown": (lambda: breakdown.energy_breakdown(R, {"drag_area_m2": THREE / 40}, np.array([1500.0, 1600.0])),
                  r"vehicle_mass_kg \(2,\), drag_area_m2 \(3,\)"),
}


@pytest.mark.parametrize("case", MISMATCHED)
def test_arrays_of_different_lengths_are_one_line_naming_them(case):
    call, names = MISMATCHED[case]
    with pytest.raises(ValueError, match=rf"^arrays of different lengths: .*{names}.*; give one length N") as err:
        call()
    assert "\n" not in str(err.value)


COMPLEX = {
    "flat": (lambda z: flat.energy_wh_per_km(R, {}, np.array([1590.0 + z]), 8.0), "vehicle_mass_kg"),
    "flat parameter": (lambda z: flat.energy_wh_per_km(R, {"drag_area_m2": 0.6 + z}, 1590.0, 8.0), "drag_area_m2"),
    "range": (lambda z: range_model.range_km(np.array([24.0 + z]), 100.0), "battery_kwh"),
    "cost": (lambda z: cost.motor_cost_usd(np.array([80.0 + z, 90.0])), "motor_kw"),
    "cost parameter": (lambda z: cost.cell_cost_usd_per_kwh(4.0 + z), "power_to_energy_ratio"),
    "mass": (lambda z: mass.motor_mass_kg(80.0 + z), "motor_kw"),
    "acceleration": (lambda z: acceleration.accel_time_0_100_s(np.array([80.0]), 8.0, np.array([1590.0 + z])),
                     "vehicle_mass_kg"),
    "quasi_static": (lambda z: qs.energy_wh_per_km(R, {}, 1590.0, np.array([8.0 + z]), 80.0), "gear_ratio"),
    "quasi_static parameter": (lambda z: qs.energy_wh_per_km(R, {"initial_soc": 0.9 + z}, 1590.0, 8.0, 80.0),
                               "initial_soc"),
    "chain parameter": (lambda z: chain.simulate(R, {"aux_power_w": 300.0 + z}, 1590.0, 8.0, 80.0), "aux_power_w"),
}


@pytest.mark.parametrize("case", COMPLEX)
def test_a_complex_value_is_refused_not_cast(case):
    call, name = COMPLEX[case]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a ComplexWarning was the only sign
        with pytest.raises(ValueError, match=rf"^{name} must be a real number in \[.*\].*, got .*complex"):
            call(1e-20j)
        call(0.0)  # the same call with a real value runs


def test_breakdown_keeps_complex_values_for_complex_step():
    """The one smooth model differentiated by complex step: its inputs stay complex."""
    h = 1e-20
    e = breakdown.energy_wh_per_km(R, {}, np.array([1590.0 + 1j * h]), 8.0, 80.0)
    assert np.iscomplexobj(e) and e.imag[0] != 0.0


@pytest.mark.parametrize("call, said", [
    (lambda: cost.powertrain_cost_usd(-5.0, 24.0), r"^motor_kw must be in \[1, 1000\] kW, got -5$"),
    (lambda: mass.battery_mass_kg(0.5), r"^battery_kwh must be in \[1, 40000\] kWh, got 0.5$"),
    (lambda: acceleration.accel_time_0_100_s(80.0, 8.0, 50.0), r"^vehicle_mass_kg must be in \[100, 20000\] kg, got 50$"),
    (lambda: range_model.range_km(24.0, 0.0), r"^energy_wh_per_km must be in \[1, inf\] Wh/km, got 0$")])
def test_a_design_value_out_of_its_range_is_named_with_its_unit(call, said):
    with pytest.raises(ValueError, match=said):
        call()


@pytest.mark.parametrize("name, value, said", [
    ("glider_kg", float("nan"), r"^glider_kg must be in \[200, 5000\] kg, got nan$"),
    ("glider_kg", np.array([1200.0, -1.0]), r"^glider_kg must be in \[200, 5000\] kg, got -1$"),
    ("load_kg", float("inf"), r"^load_kg must be in \[0, 5000\] kg, got inf$"),
    ("battery_kg_per_kwh", -7.8, r"^battery_kg_per_kwh must be in \[0.5, 50\] kg/kWh, got -7.8$")])
def test_a_mass_parameter_must_be_finite_and_physical(name, value, said):
    """The mass model checked its parameters for length only: a nan glider mass gave a nan vehicle mass."""
    with pytest.raises(ValueError, match=said):
        mass.vehicle_mass_ch7_kg(80.0, 24.0, **{name: value})
    with pytest.raises(ValueError, match=said):
        mass.vehicle_mass_kg(80.0, 24.0, {name: value})
