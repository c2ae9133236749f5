"""Battery: open-circuit voltage plus internal resistance, with state of charge.

Thesis eqs 2-9..2-15. A pack is ``cells_series`` x ``cells_parallel`` identical cells:
pack OCV = N_s * OCV_cell(SOC) (2-15), pack resistance = N_s * R_cell(SOC) / N_p,
capacity = N_p * cell Ah. ``cells_parallel`` may be fractional (a continuous design
variable for optimisers); :func:`pack_for_energy` derives it from a pack size in kWh.

Default cell (an ASSUMPTION, the thesis' Figs 3-4/3-5 are not in the text): a 33.1 Ah
Li-ion (LMO/NMC) pouch cell like the Leaf's, nominal 3.776 V so that 96s2p = 24.0 kWh.
Its OCV curve is a typical LMO/NMC shape; its resistance is 4.0 mOhm discharging and
4.5 mOhm charging at mid SOC, which gives the chapter-5 pack values 0.192 / 0.216 Ohm
for 96s2p, rising towards empty. Sign convention (2-10): current > 0 discharges.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Leaf pack (§3.3.4): 48 modules x 4 cells = 96 in series x 2 in parallel.
LEAF_CELLS_SERIES = 96
LEAF_CELLS_PARALLEL = 2
DISCHARGE_C_MAX = 5.0  # §3.5.3: discharge current <= 5C
CHARGE_C_MAX = 2.0  # §2.3.4 rule 4 / §3.5.3: charge current <= 2C


@dataclass(frozen=True)
class Cell:
    """One cell: OCV and resistances tabulated against SOC (0..1), linear in between."""

    soc: np.ndarray
    ocv_v: np.ndarray
    r_discharge_ohm: np.ndarray
    r_charge_ohm: np.ndarray
    capacity_ah: float
    nominal_v: float

    def __post_init__(self):
        s = np.asarray(self.soc, float)
        if s.ndim != 1 or len(s) < 2 or s[0] != 0.0 or s[-1] != 1.0 or np.any(np.diff(s) <= 0):
            raise ValueError("cell soc table must increase strictly from 0 to 1")
        for name in ("ocv_v", "r_discharge_ohm", "r_charge_ohm"):
            a = np.asarray(getattr(self, name), float)
            if a.shape != s.shape or not np.all(np.isfinite(a)) or np.any(a <= 0):
                raise ValueError(f"cell {name} must be finite, > 0 and as long as the soc table")
        if not (0.1 <= self.capacity_ah <= 1000):
            raise ValueError(f"cell capacity_ah must be in [0.1, 1000] Ah, got {self.capacity_ah}")
        if not (1.0 <= self.nominal_v <= 5.0):
            raise ValueError(f"cell nominal_v must be in [1, 5] V, got {self.nominal_v}")

    def ocv(self, soc):
        """Cell open-circuit voltage (V) at ``soc`` (clipped to 0..1)."""
        return np.interp(soc, self.soc, self.ocv_v)

    def resistance(self, soc, charging):
        """Cell internal resistance (Ohm): the charge curve where ``charging`` is true."""
        return np.where(charging, np.interp(soc, self.soc, self.r_charge_ohm),
                        np.interp(soc, self.soc, self.r_discharge_ohm))


_SOC = np.array([0.0, 0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0])
DEFAULT_CELL = Cell(
    soc=_SOC,
    ocv_v=np.array([3.30, 3.48, 3.56, 3.63, 3.68, 3.72, 3.76, 3.81, 3.88, 3.95, 4.03, 4.12]),
    r_discharge_ohm=4.0e-3 * np.array([1.8, 1.4, 1.2, 1.05, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.02]),
    r_charge_ohm=4.5e-3 * np.array([1.6, 1.3, 1.15, 1.05, 1.0, 1.0, 1.0, 1.0, 1.0, 1.05, 1.15, 1.4]),
    capacity_ah=33.1,
    nominal_v=24000.0 / (LEAF_CELLS_SERIES * LEAF_CELLS_PARALLEL * 33.1),
)


@dataclass(frozen=True)
class Pack:
    """A series/parallel pack; ``cells_series``/``cells_parallel`` are scalars or (N,)."""

    cells_series: np.ndarray
    cells_parallel: np.ndarray
    cell: Cell = DEFAULT_CELL

    @property
    def capacity_ah(self):
        return self.cells_parallel * self.cell.capacity_ah

    @property
    def capacity_c(self):
        """Charge capacity Q_0 in coulombs (2-9)."""
        return self.capacity_ah * 3600.0

    @property
    def energy_kwh(self):
        return self.cells_series * self.cells_parallel * self.cell.capacity_ah * self.cell.nominal_v / 1e3

    def ocv(self, soc):
        """Pack open-circuit voltage (2-15)."""
        return self.cells_series * self.cell.ocv(soc)

    def resistance(self, soc, charging):
        """Pack internal resistance: N_s cells in series, N_p strings in parallel."""
        return self.cells_series * self.cell.resistance(soc, charging) / self.cells_parallel


def pack_for_energy(battery_kwh, cells_series=LEAF_CELLS_SERIES, cell: Cell = DEFAULT_CELL) -> Pack:
    """A pack of ``battery_kwh`` with ``cells_series`` in series and a continuous parallel count."""
    kwh = np.asarray(battery_kwh, float)
    ns = np.asarray(cells_series, float)
    if not np.all(np.isfinite(kwh)) or np.any(kwh < 1.0):  # no upper limit: common.DESIGN_LIMITS says why
        raise ValueError("battery_kwh must be finite and >= 1 kWh")
    if not np.all(np.isfinite(ns)) or np.any(ns < 1) or np.any(ns > 1000):
        raise ValueError("cells_series must be finite and in [1, 1000]")
    n_par = kwh * 1e3 / (ns * cell.capacity_ah * cell.nominal_v)
    return Pack(ns, n_par, cell)


def terminal_voltage_v(power_w, ocv_v, resistance_ohm):
    """Terminal voltage for terminal power P (2-13, 2-14, the '+' root).

    Power beyond the maximum ``ocv^2 / (4 R)`` is clipped to it (voltage ocv/2)."""
    disc = np.maximum(ocv_v * ocv_v - 4.0 * power_w * resistance_ohm, 0.0)
    return 0.5 * (ocv_v + np.sqrt(disc))


def terminal_current_a(power_w, ocv_v, resistance_ohm):
    """Terminal current I = P / V_BT (2-11, 2-12); > 0 discharging, < 0 charging."""
    return power_w / terminal_voltage_v(power_w, ocv_v, resistance_ohm)


def max_discharge_power_w(ocv_v, resistance_ohm):
    """The largest terminal power the OCV + R model can deliver: ocv^2 / (4 R)."""
    return ocv_v * ocv_v / (4.0 * resistance_ohm)


def power_at_current_w(current_a, ocv_v, resistance_ohm):
    """Terminal power at terminal current I: (ocv - I R) * I (2-12)."""
    return (ocv_v - current_a * resistance_ohm) * current_a


def soc_after(soc, current_a, dt_s, capacity_c):
    """SOC after drawing ``current_a`` for ``dt_s`` from a pack of ``capacity_c`` coulombs (2-9, 2-10)."""
    return soc - current_a * dt_s / capacity_c
