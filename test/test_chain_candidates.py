"""scripts/chain_candidates.py (the physics-candidate harness of docs/validation.md): with every
extra term off it must be the shipped chain, and each extra term must act in its physical direction."""
import importlib.util
from pathlib import Path

import numpy as np
import pytest

from bev_mdo.models import calibrate as cal
from bev_mdo.models import chain
from bev_mdo.models import fleet as fl

ROOT = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("chain_candidates", ROOT / "scripts" / "chain_candidates.py")
cc = importlib.util.module_from_spec(spec)
spec.loader.exec_module(cc)

SHIPPED = {**cal.FIXED, "charger_efficiency": 0.8255, "regen_axle_share": 0.8143}


@pytest.fixture(scope="module")
def fleet_cycles():
    return fl.read_fleet(), fl.resampled_cycles()


def test_harness_without_extras_is_the_shipped_chain(fleet_cycles):
    fleet, cycles = fleet_cycles
    pred = cc.predict(fleet, SHIPPED, cycles)
    for name, r in cycles.items():
        ref = chain.simulate(r, fl.fleet_params(fleet, SHIPPED), fleet.test_mass_kg, fleet.gear_ratio,
                             fleet.rated_power_kw).energy_wh_per_km
        np.testing.assert_allclose(pred[name], ref, rtol=1e-12)


@pytest.mark.parametrize("extra, cycle", [
    ({"iron_loss_fraction": 0.01}, "epa_hwfet"),
    ({"inverter_current_fraction": 0.02}, "epa_udds"),
    ({"regen_decel_max_m_s2": 0.5}, "epa_udds"),
    ({"regen_efficiency": 0.8}, "epa_udds"),
    ({"traction_efficiency": 0.9}, "epa_hwfet"),
    ({"raf_resistance_ohm": 0.1}, "epa_hwfet"),
])
def test_each_extra_loss_raises_every_vehicles_energy(fleet_cycles, extra, cycle):
    fleet, cycles = fleet_cycles
    base = cc.predict(fleet, SHIPPED, {cycle: cycles[cycle]})[cycle]
    more = cc.predict(fleet, {**SHIPPED, **extra}, {cycle: cycles[cycle]})[cycle]
    assert np.all(more > base * (1 + 1e-4))


def test_test_wide_battery_loss_scales_both_cycles_alike(fleet_cycles):
    """J1634: one AC/DC factor per vehicle, the same on UDDS and HWFET."""
    fleet, cycles = fleet_cycles
    no_r = {**SHIPPED, "battery_discharge_resistance_ohm": 0.0, "battery_charge_resistance_ohm": 0.0}
    base = cc.predict(fleet, no_r, cycles)
    raf = cc.predict(fleet, {**no_r, "raf_resistance_ohm": 0.08}, cycles)
    np.testing.assert_allclose(raf["epa_udds"] / base["epa_udds"], raf["epa_hwfet"] / base["epa_hwfet"], rtol=1e-12)
