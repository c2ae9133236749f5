"""Drive cycles: the regulation NEDC, packaged Artemis/WLTC traces, user CSVs, resampling.

A :class:`DriveCycle` is a speed trace that is linear between its samples. Resampling
(:func:`resample`) fits a pchip or smoothing cubic spline (thesis §6.3.3) and gives the
speed, acceleration and jerk the flat model needs.
"""
from __future__ import annotations

import csv
import hashlib
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.interpolate import PchipInterpolator, make_smoothing_spline

KMH = 1.0 / 3.6  # m/s per km/h
DATA_DIR = Path(__file__).resolve().parent.parent / "data" / "drive_cycles"


@dataclass(frozen=True, eq=False)
class DriveCycle:
    """A speed trace: ``time_s`` strictly increasing, ``speed_m_s`` ≥ 0, linear in between."""

    name: str
    time_s: np.ndarray
    speed_m_s: np.ndarray

    @property
    def duration_s(self) -> float:
        return float(self.time_s[-1] - self.time_s[0])

    @property
    def distance_m(self) -> float:
        """Distance by the trapezoid rule: exact for a trace linear between samples."""
        return float(np.trapezoid(self.speed_m_s, self.time_s))

    @property
    def mean_speed_kmh(self) -> float:
        return self.distance_m / self.duration_s * 3.6

    @property
    def max_speed_kmh(self) -> float:
        return float(np.max(self.speed_m_s)) * 3.6

    def key(self) -> str:
        """A content hash, used to cache resampled cycles and precomputed moments."""
        h = hashlib.sha1(self.name.encode())
        h.update(np.ascontiguousarray(self.time_s, dtype=float).tobytes())
        h.update(np.ascontiguousarray(self.speed_m_s, dtype=float).tobytes())
        return h.hexdigest()


# UNECE R83/R101 Annex 4a, ECE-15 elementary urban cycle: (cumulative time s, speed km/h)
# at each segment boundary; speed is linear within a segment. Gear changes hold speed,
# except the 35 -> 32 km/h gear change at 176-178 s.
_ECE15 = [
    (0, 0), (11, 0), (15, 15), (23, 15), (25, 10), (28, 0), (49, 0), (54, 15), (56, 15),
    (61, 32), (85, 32), (93, 10), (96, 0), (117, 0), (122, 15), (124, 15), (133, 35),
    (135, 35), (143, 50), (155, 50), (163, 35), (176, 35), (178, 32), (185, 10), (188, 0),
    (195, 0),
]
# Extra-urban driving cycle (EUDC), 400 s.
_EUDC = [
    (0, 0), (20, 0), (25, 15), (27, 15), (36, 35), (38, 35), (46, 50), (48, 50), (61, 70),
    (111, 70), (119, 50), (188, 50), (201, 70), (251, 70), (286, 100), (316, 100),
    (336, 120), (346, 120), (362, 80), (370, 50), (380, 0), (400, 0),
]


def _from_breakpoints(name: str, points: list[tuple[float, float]]) -> DriveCycle:
    t_b, v_b = np.array(points, dtype=float).T
    t = np.arange(t_b[0], t_b[-1] + 0.5)  # 1 Hz; all breakpoints are whole seconds
    return DriveCycle(name, t, np.interp(t, t_b, v_b) * KMH)


def ece15() -> DriveCycle:
    """One ECE-15 urban cycle (195 s, 1.0146 km by the segment table; R83 quotes 1.013 km)."""
    return _from_breakpoints("ece15", _ECE15)


def eudc() -> DriveCycle:
    """The extra-urban driving cycle (400 s, 6.955 km)."""
    return _from_breakpoints("eudc", _EUDC)


def nedc() -> DriveCycle:
    """NEDC = 4 x ECE-15 + EUDC from the R83/R101 segment table: 1180 s, 11.013 km."""
    u = ece15()
    return concatenate([u, u, u, u, eudc()], "nedc")


def concatenate(cycles: list[DriveCycle], name: str) -> DriveCycle:
    """Join cycles end to end. Equal speeds at a joint are merged into one sample;
    otherwise the next cycle starts one of its own sample steps after the previous end."""
    if not cycles:
        raise ValueError("concatenate: need at least one cycle")
    ts, vs = [cycles[0].time_s - cycles[0].time_s[0]], [cycles[0].speed_m_s]
    for c in cycles[1:]:
        t_end, v_end = ts[-1][-1], vs[-1][-1]
        t = c.time_s - c.time_s[0]
        if math.isclose(c.speed_m_s[0], v_end, abs_tol=1e-12):
            ts.append(t[1:] + t_end)
            vs.append(c.speed_m_s[1:])
        else:
            step = t[1] if len(t) > 1 else 1.0
            ts.append(t + t_end + step)
            vs.append(c.speed_m_s)
    return DriveCycle(name, np.concatenate(ts), np.concatenate(vs))


def read_cycle_csv(path: str | Path) -> DriveCycle:
    """Read a ``time_s,speed_kmh`` CSV; ValueError naming the file and row on bad data."""
    path = Path(path)
    try:
        with path.open(newline="") as f:
            rows = list(csv.reader(f))
    except OSError as exc:
        raise ValueError(f"cannot read drive cycle {path}: {exc.strerror}") from None
    if not rows or [h.strip() for h in rows[0]] != ["time_s", "speed_kmh"]:
        raise ValueError(f"{path}: row 1: header must be 'time_s,speed_kmh'")
    t, v = [], []
    for i, row in enumerate(rows[1:], start=2):
        if not row or all(not c.strip() for c in row):
            continue
        if len(row) != 2:
            raise ValueError(f"{path}: row {i}: expected 2 columns time_s,speed_kmh, got {len(row)}")
        try:
            ti, vi = float(row[0]), float(row[1])
        except ValueError:
            raise ValueError(f"{path}: row {i}: not a number: {','.join(row)}") from None
        if not math.isfinite(ti):
            raise ValueError(f"{path}: row {i}: time_s must be finite, got {row[0]}")
        if not math.isfinite(vi) or vi < 0:
            raise ValueError(f"{path}: row {i}: speed_kmh must be finite and >= 0, got {row[1]}")
        if t and ti <= t[-1]:
            raise ValueError(f"{path}: row {i}: time_s must be strictly increasing ({ti} after {t[-1]})")
        t.append(ti)
        v.append(vi)
    if len(t) < 2:
        raise ValueError(f"{path}: needs at least 2 data rows, got {len(t)}")
    return DriveCycle(path.stem, np.array(t), np.array(v) * KMH)


PACKAGED = ("artemis_urban", "artemis_rural_road", "artemis_motorway_130",
            "artemis_motorway_150", "wltc_class3")
CYCLE_NAMES = ("nedc", "artemis_combined") + PACKAGED


def artemis_combined() -> DriveCycle:
    """Thesis §2.1.1: 2 x urban + 2 x rural + 1 x motorway (the 130 km/h one: Table 2-2
    gives 28.74 km and 132 km/h max). The packaged urban segment is 993 s; the thesis' 920 s."""
    u, r, m = (read_cycle_csv(DATA_DIR / f"{n}.csv") for n in
               ("artemis_urban", "artemis_rural_road", "artemis_motorway_130"))
    return concatenate([u, u, r, r, m], "artemis_combined")


def load_cycle(name_or_path: str) -> DriveCycle:
    """A cycle by name (see ``CYCLE_NAMES``) or from a CSV path."""
    key = str(name_or_path).strip()
    if key.lower() == "nedc":
        return nedc()
    if key.lower() == "artemis_combined":
        return artemis_combined()
    if key.lower() in PACKAGED:
        c = read_cycle_csv(DATA_DIR / f"{key.lower()}.csv")
        return DriveCycle(key.lower(), c.time_s, c.speed_m_s)
    p = Path(key)
    if p.suffix.lower() == ".csv" or p.exists():
        return read_cycle_csv(p)
    raise ValueError(f"unknown drive cycle {key!r}: use one of {', '.join(CYCLE_NAMES)} or a CSV path")


@dataclass(frozen=True, eq=False)
class Resampled:
    """A cycle on a uniform grid with speed, acceleration and jerk from one interpolant."""

    name: str
    dt_s: float
    time_s: np.ndarray
    speed_m_s: np.ndarray
    accel_m_s2: np.ndarray
    jerk_m_s3: np.ndarray

    @property
    def distance_m(self) -> float:
        """Trapezoid distance of the resampled speed."""
        return float(np.trapezoid(self.speed_m_s, self.time_s))

    def key(self) -> str:
        h = hashlib.sha1(f"{self.name}|{self.dt_s!r}".encode())
        for a in (self.time_s, self.speed_m_s, self.accel_m_s2, self.jerk_m_s3):
            h.update(np.ascontiguousarray(a, dtype=float).tobytes())
        return h.hexdigest()


_CACHE: dict[tuple, Resampled] = {}
METHODS = ("pchip", "spline")


def resample(cycle: DriveCycle, dt_s: float = 1.0, method: str = "pchip",
             smoothing: float | None = None) -> Resampled:
    """Resample ``cycle`` every ``dt_s`` seconds with a shape-preserving cubic ("pchip")
    or a smoothing cubic spline ("spline", thesis §6.3.3; ``smoothing`` is the penalty
    lambda, None = chosen by generalised cross-validation). Results are cached."""
    if not (isinstance(dt_s, (int, float)) and math.isfinite(dt_s) and 0.01 <= dt_s <= 10.0):
        raise ValueError(f"cycle dt_s must be in [0.01, 10] s, got {dt_s!r}")
    if method not in METHODS:
        raise ValueError(f"cycle interpolation must be one of {list(METHODS)}, got {method!r}")
    if smoothing is not None and not (math.isfinite(smoothing) and smoothing >= 0):
        raise ValueError(f"cycle smoothing must be finite and >= 0, got {smoothing!r}")
    key = (cycle.key(), float(dt_s), method, smoothing)
    hit = _CACHE.get(key)
    if hit is not None:
        return hit
    t0 = cycle.time_s[0]
    n = int(math.floor(cycle.duration_s / dt_s + 1e-9))
    t = t0 + dt_s * np.arange(n + 1)
    if method == "pchip":
        f = PchipInterpolator(cycle.time_s, cycle.speed_m_s, extrapolate=False)
    else:
        f = make_smoothing_spline(cycle.time_s, cycle.speed_m_s, lam=smoothing)
    d1, d2 = f.derivative(1), f.derivative(2)
    out = Resampled(cycle.name, float(dt_s), t, np.asarray(f(t), float),
                    np.asarray(d1(t), float), np.asarray(d2(t), float))
    for a in (out.time_s, out.speed_m_s, out.accel_m_s2, out.jerk_m_s3):
        a.setflags(write=False)
    if len(_CACHE) > 64:
        _CACHE.clear()
    _CACHE[key] = out
    return out
