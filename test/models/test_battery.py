"""Battery OCV + R pack (eqs 2-9..2-15), values computed by hand."""
import math

import numpy as np
import pytest

from bev_mdo.models import battery as bt


def test_pack_for_energy_leaf_is_96s2p():
    pack = bt.pack_for_energy(24.0)
    assert float(pack.cells_parallel) == pytest.approx(2.0)
    assert float(pack.capacity_ah) == pytest.approx(66.2)
    assert float(pack.energy_kwh) == pytest.approx(24.0)
    # 48 kWh with the same series count doubles the strings
    assert float(bt.pack_for_energy(48.0).cells_parallel) == pytest.approx(4.0)


def test_ocv_and_resistance_by_hand():
    pack = bt.pack_for_energy(24.0)
    # eq 2-15: 96 x cell OCV; SOC 0.55 is halfway between the 0.5 (3.76 V) and 0.6 (3.81 V) rows
    assert float(pack.ocv(0.55)) == pytest.approx(96 * 3.785)
    # ch.5 pack values at mid SOC: 96 x 4.0 mOhm / 2 = 0.192 Ohm, 96 x 4.5 mOhm / 2 = 0.216 Ohm
    assert float(pack.resistance(0.5, False)) == pytest.approx(0.192)
    assert float(pack.resistance(0.5, True)) == pytest.approx(0.216)


def test_terminal_voltage_and_current_by_hand():
    voc, r, p = 360.0, 0.2, 50e3
    v = (360.0 + math.sqrt(360.0 ** 2 - 4 * 50e3 * 0.2)) / 2  # eq 2-14, '+' root
    assert float(bt.terminal_voltage_v(p, voc, r)) == pytest.approx(v)
    i = float(bt.terminal_current_a(p, voc, r))
    assert i == pytest.approx(p / v)  # 2-11
    assert voc - i * r == pytest.approx(v)  # 2-12
    # charging: P < 0 gives V above OCV and negative current
    ic = float(bt.terminal_current_a(-20e3, voc, r))
    assert ic < 0 and float(bt.terminal_voltage_v(-20e3, voc, r)) > voc
    assert float(bt.power_at_current_w(ic, voc, r)) == pytest.approx(-20e3)


def test_max_power_clips_at_half_ocv():
    voc, r = 300.0, 0.5
    pmax = float(bt.max_discharge_power_w(voc, r))
    assert pmax == pytest.approx(300.0 ** 2 / 2.0)
    assert float(bt.terminal_voltage_v(2 * pmax, voc, r)) == pytest.approx(150.0)


def test_soc_after_coulomb_count():
    # 66.2 Ah pack, 66.2 A for 360 s = 0.1 of the charge (2-9, 2-10)
    assert float(bt.soc_after(0.8, 66.2, 360.0, 66.2 * 3600)) == pytest.approx(0.7)
    assert float(bt.soc_after(0.5, -10.0, 10.0, 3600.0)) == pytest.approx(0.5 + 100 / 3600)


def test_vectorised_pack():
    pack = bt.pack_for_energy(np.array([24.0, 36.0]), np.array([96, 108]))
    soc = np.array([0.3, 0.9])
    np.testing.assert_allclose(pack.ocv(soc), [96 * 3.68, 108 * 4.03])
    np.testing.assert_allclose(pack.capacity_ah, 1e3 * np.array([24.0, 36.0]) /
                               (np.array([96, 108]) * bt.DEFAULT_CELL.nominal_v))


@pytest.mark.parametrize("kwh,ns,match", [(-1.0, 96, "battery_kwh"), (np.nan, 96, "battery_kwh"),
                                          (24.0, 0, "cells_series")])
def test_bad_inputs(kwh, ns, match):
    with pytest.raises(ValueError, match=match):
        bt.pack_for_energy(kwh, ns)


def test_bad_cell_table():
    c = bt.DEFAULT_CELL
    with pytest.raises(ValueError, match="soc table"):
        bt.Cell(np.array([0.0, 0.5]), c.ocv_v[:2], c.r_discharge_ohm[:2], c.r_charge_ohm[:2], 10.0, 3.7)
