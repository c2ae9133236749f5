"""Motor efficiency map (torque x speed) and the torque envelope, scaled by motor size.

Thesis eqs 2-7, 2-8 and Fig 2-9 / §3.3.3: the map belongs to a unit motor of
``reference_kw`` (80 kW, 280 Nm peak); a motor of P kW uses the same map with the torque
axis multiplied by P / 80 (efficiency at (T, w) = unit efficiency at (T * 80 / P, w)).
Speed is limited at 10 500 rpm for every size. Regeneration has the same efficiency as
traction unless the map has negative-torque rows. Electrical power (2-7, §3.3.3):
P_el = T w / eta when motoring, T w * eta when regenerating. The efficiency is bilinear on the
grid, clamped at its edges, read through np.interp's fractional grid positions: the operations
the compiled loops repeat (compiled._electrical_w), so the numpy and compiled models agree to the
bit (scipy's RegularGridInterpolator differed by an ulp, which a pack at its power limit amplified
to 1e-10).

Envelope: 3.5 Nm/kW constant torque up to base speed, constant power above
it, nothing beyond max speed. The base speed is then 1000 / 3.5 = 285.7 rad/s for all sizes.

Default map (an ASSUMPTION, Fig 3-2's Leaf map is not in the text): efficiency from a loss
model of a typical 80 kW PMSM, P_loss = k_cu T^2 + k_fe w + k_w w^2 + P_0 with
k_cu = 0.085 W/Nm^2 (copper), k_fe = 2.5 W s/rad (iron, hysteresis), k_w = 1.6e-3 W s^2/rad^2
(eddy + windage), P_0 = 300 W (friction, inverter idle). Inside the envelope this peaks at
95.4 % near 620 rad/s, 130 Nm, gives 91 % at the 80 kW corner and 79 % at 280 Nm, 100 rad/s,
in line with the 85-95 % of Fig 3-2.

CSV format (``load_motor_map_csv``), long form, one grid point per row::

    # comment lines start with '#'
    speed_rad_s,torque_nm,efficiency
    0,0,0.05
    0,5,0.05
    ...

The rows must cover a full regular grid (every speed with every torque, any order);
speeds >= 0, efficiency in (0, 1]. Torques >= 0 are used for both quadrants (|T| is
looked up when regenerating); if the grid also has negative torques, regeneration
uses those rows instead. The torque axis belongs to a motor of ``reference_kw``.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .cycles import csv_number, header_text, read_csv_rows
from .params import VEHICLE_SPECS

REFERENCE_KW = VEHICLE_SPECS["reference_motor_kw"].default  # Fig 2-9 unit motor, 80 kW
TORQUE_PER_KW_NM = VEHICLE_SPECS["motor_torque_per_kw"].default  # 280 Nm / 80 kW
MAX_SPEED_RAD_S = VEHICLE_SPECS["motor_speed_limit_rpm"].default * 2.0 * math.pi / 60.0  # 1099.6 rad/s, §3.3.3
EFFICIENCY_FLOOR = 0.05  # lookups below this are raised to it (no 0/0 at zero speed)
DEFAULT_MAP_CSV = Path(__file__).resolve().parent.parent / "data" / "motor_map_default.csv"

# Default loss-model coefficients for the 80 kW unit motor (see module docstring).
LOSS_COPPER_W_PER_NM2 = 0.085
LOSS_IRON_W_S_PER_RAD = 2.5
LOSS_EDDY_W_S2_PER_RAD2 = 1.6e-3
LOSS_CONST_W = 300.0


def base_speed_rad_s(motor_kw=REFERENCE_KW):
    """Base speed: peak power over peak torque (285.7 rad/s for any size)."""
    return 1000.0 / TORQUE_PER_KW_NM + 0.0 * np.asarray(motor_kw, float)


def max_torque_nm(speed_rad_s, motor_kw, max_speed_rad_s=MAX_SPEED_RAD_S):
    """Envelope: 3.5 Nm/kW up to base speed, P / w above it, 0 beyond max speed."""
    w = np.asarray(speed_rad_s, float)
    p_w = np.asarray(motor_kw, float) * 1e3
    t_pk = TORQUE_PER_KW_NM * np.asarray(motor_kw, float)
    with np.errstate(divide="ignore"):
        t = np.minimum(t_pk, p_w / np.maximum(np.abs(w), 1e-9))
    return np.where(np.abs(w) <= max_speed_rad_s, t, 0.0)


def loss_model_w(torque_nm, speed_rad_s):
    """Default unit-motor losses (W) at |T|, |w| (copper, iron, eddy/windage, constant)."""
    t = np.abs(torque_nm)
    w = np.abs(speed_rad_s)
    return (LOSS_COPPER_W_PER_NM2 * t * t + LOSS_IRON_W_S_PER_RAD * w
            + LOSS_EDDY_W_S2_PER_RAD2 * w * w + LOSS_CONST_W)


@dataclass(frozen=True, eq=False)
class MotorMap:
    """Efficiency on a regular (speed, torque) grid for a motor of ``reference_kw``."""

    speed_rad_s: np.ndarray
    torque_nm: np.ndarray
    efficiency: np.ndarray  # shape (len(speed_rad_s), len(torque_nm))
    reference_kw: float = REFERENCE_KW
    name: str = "map"

    def __post_init__(self):
        w = np.asarray(self.speed_rad_s, float)
        t = np.asarray(self.torque_nm, float)
        e = np.asarray(self.efficiency, float)
        if w.ndim != 1 or len(w) < 2 or np.any(np.diff(w) <= 0) or w[0] < 0:
            raise ValueError(f"motor map {self.name}: speeds must be >= 0 and strictly increasing")
        if t.ndim != 1 or len(t) < 2 or np.any(np.diff(t) <= 0):
            raise ValueError(f"motor map {self.name}: torques must be strictly increasing")
        if e.shape != (len(w), len(t)) or not np.all(np.isfinite(e)) or np.any(e <= 0) or np.any(e > 1):
            raise ValueError(f"motor map {self.name}: efficiency must be in (0, 1] on the full grid")
        if not (math.isfinite(self.reference_kw) and 1.0 <= self.reference_kw <= 1000.0):
            raise ValueError(f"motor map {self.name}: reference_kw must be in [1, 1000] kW")
        for k, a in (("speed_rad_s", w), ("torque_nm", t), ("efficiency", e)):  # the lookups index arrays
            object.__setattr__(self, k, a)

    @property
    def has_regen_rows(self) -> bool:
        return bool(self.torque_nm[0] < 0)

    def efficiency_at(self, torque_nm, speed_rad_s, motor_kw):
        """Efficiency of a ``motor_kw`` motor at (T, w), bilinear on the grid and clamped at its edges
        (see the module doc); arrays broadcast together."""
        t, w = np.asarray(torque_nm, float), np.asarray(speed_rad_s, float)
        tu = t * (self.reference_kw / np.asarray(motor_kw, float))  # Fig 2-9 torque-axis scaling
        if not self.has_regen_rows:
            tu = np.abs(tu)
        wg, tg, e = self.speed_rad_s, self.torque_nm, self.efficiency
        fi = np.interp(np.abs(w), wg, np.arange(len(wg), dtype=float))  # fractional grid positions
        fj = np.interp(tu, tg, np.arange(len(tg), dtype=float))
        i0 = np.minimum(fi.astype(np.intp), len(wg) - 2)
        j0 = np.minimum(fj.astype(np.intp), len(tg) - 2)
        a, b = fi - i0, fj - j0
        e00, e01, e10, e11 = e[i0, j0], e[i0, j0 + 1], e[i0 + 1, j0], e[i0 + 1, j0 + 1]
        return np.maximum((1 - a) * ((1 - b) * e00 + b * e01) + a * ((1 - b) * e10 + b * e11), EFFICIENCY_FLOOR)

    def electrical_power_w(self, torque_nm, speed_rad_s, motor_kw):
        """Electrical power (W): T w / eta motoring, T w * eta regenerating (2-7, §3.3.3)."""
        pm = np.asarray(torque_nm, float) * np.asarray(speed_rad_s, float)
        eta = self.efficiency_at(torque_nm, speed_rad_s, motor_kw)
        return np.where(pm >= 0, pm / eta, pm * eta)


def default_motor_map() -> MotorMap:
    """The documented default unit map (80 kW / 280 Nm) from the loss model."""
    w = np.r_[0.0, 10.0, 20.0, 40.0, np.arange(60.0, 1100.0 + 1e-9, 20.0)]
    t = np.r_[0.0, 5.0, 10.0, np.arange(20.0, 280.0 + 1e-9, 10.0)]
    W, T = np.meshgrid(w, t, indexing="ij")
    p = W * T
    eta = p / (p + loss_model_w(T, W))
    return MotorMap(w, t, np.clip(np.round(eta, 4), EFFICIENCY_FLOOR, 1.0),
                    REFERENCE_KW, "default_pmsm_80kw")


def write_motor_map_csv(motor_map: MotorMap, path) -> None:
    """Write a map in the long CSV format read by :func:`load_motor_map_csv`."""
    with Path(path).open("w", newline="") as f:
        f.write(f"# bev_mdo motor map '{motor_map.name}', torque axis for {motor_map.reference_kw:g} kW\n")
        wr = csv.writer(f)
        wr.writerow(["speed_rad_s", "torque_nm", "efficiency"])
        for i, w in enumerate(motor_map.speed_rad_s):
            for j, t in enumerate(motor_map.torque_nm):
                wr.writerow([f"{w:g}", f"{t:g}", f"{motor_map.efficiency[i, j]:.4f}"])


def load_motor_map_csv(path, reference_kw: float = REFERENCE_KW) -> MotorMap:
    """Read a long-form ``speed_rad_s,torque_nm,efficiency`` CSV (see module docstring) through the
    strict reader of every user CSV (cycles.read_csv_rows); ValueError '<file>: row R: ...' on bad data."""
    path = Path(path)
    rows = [(i, r) for i, r in enumerate(read_csv_rows(path, "motor map"), start=1)
            if r and not r[0].lstrip().startswith("#") and any(c.strip() for c in r)]
    if not rows or [c.strip() for c in rows[0][1]] != ["speed_rad_s", "torque_nm", "efficiency"]:
        raise ValueError(f"{path}: row {rows[0][0] if rows else 1}: header must be 'speed_rad_s,torque_nm,efficiency', "
                         f"got {header_text(rows[0][1] if rows else [])}")
    data = []
    for row_no, r in rows[1:]:
        if len(r) != 3:
            raise ValueError(f"{path}: row {row_no}: need 3 numbers speed_rad_s,torque_nm,efficiency, got {len(r)}")
        vals = []
        for name, cell in zip(("speed_rad_s", "torque_nm", "efficiency"), r):
            try:
                vals.append(csv_number(cell))
            except ValueError as exc:  # not a number (1_0 was 10), or not finite
                raise ValueError(f"{path}: row {row_no}, column {name}: {exc}") from None
        if vals[0] < 0 or not (0 < vals[2] <= 1):
            raise ValueError(f"{path}: row {row_no}: speed_rad_s must be >= 0 and efficiency in (0, 1]")
        data.append(vals)
    a = np.array(data, float).reshape(-1, 3)
    w, t = np.unique(a[:, 0]), np.unique(a[:, 1])
    if len(a) != len(w) * len(t):
        raise ValueError(f"{path}: rows do not form a full speed x torque grid "
                         f"({len(a)} rows for {len(w)} speeds x {len(t)} torques)")
    eff = np.full((len(w), len(t)), np.nan)
    eff[np.searchsorted(w, a[:, 0]), np.searchsorted(t, a[:, 1])] = a[:, 2]
    if np.isnan(eff).any():
        raise ValueError(f"{path}: duplicate grid points; every speed x torque must appear once")
    return MotorMap(w, t, eff, reference_kw, path.stem)
