"""Drive cycles: the regulation NEDC, packaged Artemis/WLTC/EPA traces, user CSVs, resampling.

A :class:`DriveCycle` is a speed trace that is linear between its samples (the NEDC by its
R83/R101 segment table; 1 Hz traces such as WLTC, Artemis, UDDS and HWFET by convention).
Resampling (:func:`resample`) has three methods:

* ``linear`` (default): the trace as it is, piecewise linear. The grid is every ``dt_s``
  plus every breakpoint of the trace, so each step lies inside one linear segment; the
  acceleration is constant on a step and the jerk is zero inside it. Models integrate a step
  exactly for polynomial integrands up to cubic order (two-point Gauss-Legendre,
  :func:`quadrature`) or by the step mean speed (the thesis' eqs 6-50/6-51, exact for
  distance and kinetic energy).
* ``pchip`` and ``spline``: a shape-preserving or smoothing cubic (thesis §6.3.3), kept to
  reproduce the thesis. pchip's zero slopes at the ends of every NEDC ramp remove about 10 %
  of the inertia work (docs/validation.md).

Traces are validated on reading (:func:`check_trace`): strictly increasing time, gaps of at
most ``MAX_GAP_S``, speeds in [0, ``MAX_SPEED_KMH``], accelerations within ``MAX_ACCEL_M_S2``,
and a cycle that moves. The numbers of every user CSV (drive cycles, fleet files, motor maps, sweep
lists) are read by :func:`csv_number`: plain decimal numbers only.
"""
from __future__ import annotations

import csv
import hashlib
import itertools
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np

KMH = 1.0 / 3.6  # m/s per km/h
MAX_CSV_ROWS = 1_000_000     # a user's CSV, read whole: 48 h at 5.8 Hz (the reader holds ~0.5 GB of rows then)
MAX_CSV_BYTES = 32 * 2**20
MAX_GAP_S = 3600.0          # longest time between two samples of a trace
MAX_DURATION_S = 172800.0   # 48 h: bounds the resampled grid (1.7e7 samples at 0.01 s)
MAX_SPEED_KMH = 500.0       # faster than any road vehicle
MAX_ACCEL_M_S2 = 20.0       # 2 g between two samples: beyond any tyre
MIN_DISTANCE_M = 1.0        # a cycle that moves
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


def read_csv_rows(path, what: str) -> list[list[str]]:
    """Every row of a user's CSV: drive cycles here, fleet files in fleet.py (``what``: "drive cycle",
    "fleet file", for the message). Read as utf-8-sig: a BOM (Excel's "CSV UTF-8") is not data.
    One-line ValueError naming the file (and row) when it cannot be read, is not UTF-8, or is not a CSV
    table: a field beyond csv's 128 KiB limit, a quote closed inside a field (``"a"b``), a quote left
    open, or a field that holds a line break (a quote left open took the rows after it into one field
    and the file still parsed: a vehicle fewer, another's values under its name). So a row is one line
    of the file, and row N is line N."""
    try:
        size = os.stat(path).st_size
        if size > MAX_CSV_BYTES:
            raise ValueError(f"{path}: {size:,} bytes, more than a {what} may be ({MAX_CSV_BYTES:,} bytes, "
                             f"{MAX_CSV_ROWS:,} rows)")
        rows: list[list[str]] = []
        with open(path, newline="", encoding="utf-8-sig") as f:
            reader = csv.reader(f, strict=True)
            for row in reader:  # memory bounded before any check
                if reader.line_num != len(rows) + 1:
                    raise csv.Error("a line break in a field")
                rows.append(row)
                if len(rows) > MAX_CSV_ROWS:
                    raise ValueError(f"{path}: more than {MAX_CSV_ROWS:,} rows, more than a {what} may have")
        return rows
    except OSError as exc:
        raise ValueError(f"cannot read {what} {path}: {exc.strerror}") from None
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a UTF-8 text CSV") from None
    except csv.Error as exc:
        row = len(rows) + 1
        if reader.line_num > row:
            why = f"a field runs over a line break into row {reader.line_num} (a quote left open?)"
        elif "end of data" in str(exc):
            why = "a quote left open (the file ends inside its field)"
        else:
            why = f"not a CSV table: {exc}" + (' (a quote inside a quoted field is written twice: "")'
                                               if "expected after" in str(exc) else "")
        raise ValueError(f"{path}: row {row}: {why}") from None


_CSV_NUMBER = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")


def csv_number(cell: str) -> float:
    """A number in a user's CSV: ASCII digits with an optional sign, decimal point and exponent (spaces
    around it are allowed). ValueError ("not a number: '1_0'" or "must be finite, got nan") for what
    float() reads besides: 1_0 as 10, nan, inf, 1e999, other scripts' digits; the caller names the file,
    row and column."""
    text = cell.strip()
    if _CSV_NUMBER.fullmatch(text):
        x = float(text)
        if math.isfinite(x):
            return x
    elif text.lstrip("+-").lower() not in ("nan", "inf", "infinity"):
        raise ValueError(f"not a number: {text!r}")
    raise ValueError(f"must be finite, got {text}")


def header_text(row: list[str]) -> str:
    """A CSV's header row as an error quotes it: 'time_s,speed_mph', cut at 60 characters; 'nothing' if empty."""
    text = ",".join(c.strip() for c in row)
    return repr(text[:60] + ("..." if len(text) > 60 else "")) if text else "nothing"


def read_cycle_csv(path: str | Path) -> DriveCycle:
    """Read a ``time_s,speed_kmh`` CSV; ValueError naming the file and row on bad data."""
    path = Path(path)
    rows = read_csv_rows(path, "drive cycle")
    if not rows or [h.strip() for h in rows[0]] != ["time_s", "speed_kmh"]:
        raise ValueError(f"{path}: row 1: header must be 'time_s,speed_kmh', got {header_text(rows[0] if rows else [])}"
                         " (time in s, speed in km/h: convert mph x 1.609344, m/s x 3.6)")
    data = [(i, row) for i, row in enumerate(rows[1:], start=2) if row and any(c.strip() for c in row)]
    # rows up to the first that is not two numbers are checked below at once; that row's own error
    # is reported only if no earlier row fails a check (the first bad row is named, as a loop would)
    end, broken = len(data), ""
    for k, (_, row) in enumerate(data):
        if len(row) != 2:
            end, broken = k, f": expected 2 columns time_s,speed_kmh, got {len(row)}"
            break
    try:
        tv = np.array([(csv_number(a), csv_number(b)) for _, (a, b) in data[:end]], dtype=float).reshape(-1, 2)
    except ValueError:
        for k, (_, row) in enumerate(data[:end]):
            try:
                for column, cell in zip(("time_s", "speed_kmh"), row):
                    csv_number(cell)
            except ValueError as exc:
                end, broken = k, f", column {column}: {exc}"
                break
        tv = np.array([(csv_number(a), csv_number(b)) for _, (a, b) in data[:end]], dtype=float).reshape(-1, 2)
    t, v = tv[:, 0], tv[:, 1]
    # every row check at once; the first row that fails any is reported, checks in this order
    later = np.arange(len(t)) > 0  # the step checks start at the second row
    prev_t = np.concatenate([t[:1], t[:-1]])
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        step = t - prev_t
        accel = np.abs(v - np.concatenate([v[:1], v[:-1]])) * KMH / step
    checks = (  # (every value is a finite number: csv_number)
        (~(v >= 0), lambda k: f"speed_kmh must be >= 0, got {data[k][1][1].strip()}"),
        (v > MAX_SPEED_KMH, lambda k: f"speed_kmh {v[k]:g} is not plausible (> {MAX_SPEED_KMH:g} km/h)"),
        (later & ~(step > 0), lambda k: f"time_s must be strictly increasing ({t[k]:g} after {prev_t[k]:g})"),
        (later & (step > MAX_GAP_S), lambda k: f"time gap of {step[k]:g} s after {prev_t[k]:g} s "
                                     f"(at most {MAX_GAP_S:g} s between samples)"),
        (later & (accel > MAX_ACCEL_M_S2), lambda k: f"acceleration {(v[k] - v[k - 1]) * KMH / step[k]:g} m/s^2 "
                                           f"is not plausible (|a| > {MAX_ACCEL_M_S2:g} m/s^2)"),
    )
    bad = np.zeros(len(t), bool)
    for mask, _ in checks:
        bad |= mask
    if bad.any():
        k = int(np.argmax(bad))
        message = next(say for mask, say in checks if mask[k])
        raise ValueError(f"{path}: row {data[k][0]}: {message(k)}")
    if broken:
        raise ValueError(f"{path}: row {data[end][0]}{broken}")
    if len(t) < 2:
        raise ValueError(f"{path}: needs at least 2 data rows, got {len(t)}")
    c = DriveCycle(path.stem, t.copy(), v * KMH)
    check_trace(c, str(path))
    return c


def check_trace(cycle: DriveCycle, where: str | None = None) -> DriveCycle:
    """ValueError (one line, naming ``where``) unless the trace is usable: strictly increasing,
    gaps <= MAX_GAP_S, duration <= MAX_DURATION_S, speeds in [0, MAX_SPEED_KMH], |a| <=
    MAX_ACCEL_M_S2, distance >= MIN_DISTANCE_M."""
    w = where or cycle.name
    t, v = np.asarray(cycle.time_s, float), np.asarray(cycle.speed_m_s, float)
    if t.ndim != 1 or t.shape != v.shape or t.size < 2:
        raise ValueError(f"{w}: a drive cycle needs matching 1-D time and speed with >= 2 samples")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(v))):
        raise ValueError(f"{w}: time and speed must be finite")
    dt = np.diff(t)
    checks = [(dt <= 0, "time_s must be strictly increasing"),
              (dt > MAX_GAP_S, f"time gap above {MAX_GAP_S:g} s"),
              (v[1:] < 0, "speed must be >= 0"),
              (v[1:] > MAX_SPEED_KMH * KMH, f"speed above {MAX_SPEED_KMH:g} km/h"),
              (np.abs(np.diff(v)) > MAX_ACCEL_M_S2 * np.where(dt > 0, dt, np.inf), "implausible acceleration")]
    if v[0] < 0 or v[0] > MAX_SPEED_KMH * KMH:
        raise ValueError(f"{w}: sample 1: speed {v[0] / KMH:g} km/h outside [0, {MAX_SPEED_KMH:g}]")
    for bad, what in checks:
        if bad.any():
            k = int(np.flatnonzero(bad)[0]) + 2
            raise ValueError(f"{w}: sample {k} (t = {t[k - 1]:g} s): {what}")
    if t[-1] - t[0] > MAX_DURATION_S:
        raise ValueError(f"{w}: duration {t[-1] - t[0]:g} s above {MAX_DURATION_S:g} s")
    if not cycle.distance_m >= MIN_DISTANCE_M:
        raise ValueError(f"{w}: the cycle does not move (distance {cycle.distance_m:.3g} m)")
    return cycle


class CycleNote(UserWarning):
    """Something about a drive cycle (or a fleet file) a user should know, that is not an error (the CLI
    prints it as a ``note:`` line on stderr)."""


def unbalanced_note(cycle: DriveCycle, where: str, mass_kg: float = 1500.0) -> str | None:
    """A note when the trace does not end at the speed it starts at: the car then gains (or loses)
    kinetic energy over the trace, which a cycle from rest to rest does not, so its energy per km is
    overstated (or understated) by up to 1/2 M (v1^2 - v0^2) per km. None below 0.1 Wh/km at
    ``mass_kg`` (every packaged cycle starts and ends at rest)."""
    v0, v1 = float(cycle.speed_m_s[0]), float(cycle.speed_m_s[-1])
    wh_per_km = 0.5 * mass_kg * (v1 * v1 - v0 * v0) / 3600.0 / (cycle.distance_m / 1e3)
    if abs(wh_per_km) < 0.1:
        return None
    return (f"{where} starts at {v0 / KMH:.0f} km/h and ends at {v1 / KMH:.0f} km/h: the car "
            f"{'gains' if wh_per_km > 0 else 'loses'} kinetic energy over the trace, which a cycle from rest to rest "
            f"does not, so energies per km on it are {'overstated' if wh_per_km > 0 else 'understated'} by up to about "
            f"{abs(wh_per_km):.1f} Wh/km for a {mass_kg:.0f} kg car (end the trace at the speed it starts at)")


def is_csv_cycle(name: str) -> bool:
    """Whether a cycle name is a file of the user's (not a built-in or packaged cycle)."""
    return str(name).strip().lower() not in CYCLE_NAMES


def trace_record(cycle: DriveCycle) -> dict[str, list[float]]:
    """A cycle as a config's ``cycle_traces`` entry (YAML and JSON keep these floats bit for bit)."""
    return {"time_s": [float(t) for t in cycle.time_s], "speed_m_s": [float(v) for v in cycle.speed_m_s]}


def trace_yaml_chars(record: Mapping[str, list[float]]) -> int:
    """The characters a ``cycle_traces`` entry takes in a resolved config's YAML (``yaml.safe_dump``, block
    style: a line ``    - VALUE`` per sample value, VALUE ``repr`` of the float with ``.0`` put before a bare
    exponent), its two keys left out. A run's resolved config is what its bag stores and its nodes read, as YAML
    of at most ``yamlload.MAX_YAML_BYTES``: a trace is refused when it is read if it could not be read back."""
    chars = 0
    for values in record.values():
        text = [repr(x) for x in values]
        chars += sum(map(len, text)) + 7 * len(text) + 2 * sum("e" in t and "." not in t for t in text)
    return chars


def trace_cycle(key: str, record: Any) -> DriveCycle:
    """The cycle of a ``cycle_traces`` entry, checked as a CSV is (ValueError naming it)."""
    where = f"cycle_traces[{key!r}]"
    if not isinstance(record, Mapping) or set(record) != {"time_s", "speed_m_s"}:
        raise ValueError(f"{where} must be {{time_s: [...], speed_m_s: [...]}}")
    try:
        t, v = (np.asarray(record[k], dtype=float) for k in ("time_s", "speed_m_s"))
    except (TypeError, ValueError):
        raise ValueError(f"{where}: time_s and speed_m_s must be lists of numbers") from None
    return check_trace(DriveCycle(Path(key).stem, t, v), where)


PACKAGED = ("artemis_urban", "artemis_rural_road", "artemis_motorway_130",
            "artemis_motorway_150", "wltc_class3", "epa_udds", "epa_hwfet", "epa_us06")
CYCLE_NAMES = ("nedc", "artemis_combined") + PACKAGED


def artemis_combined() -> DriveCycle:
    """Thesis §2.1.1: 2 x urban + 2 x rural + 1 x motorway (the 130 km/h one: Table 2-2
    gives 28.74 km and 132 km/h max). The packaged urban segment is 993 s; the thesis' 920 s."""
    u, r, m = (read_cycle_csv(DATA_DIR / f"{n}.csv") for n in
               ("artemis_urban", "artemis_rural_road", "artemis_motorway_130"))
    return concatenate([u, u, r, r, m], "artemis_combined")


def load_cycle(name_or_path: str, traces: Mapping[str, Any] | None = None) -> DriveCycle:
    """A cycle by name (see ``CYCLE_NAMES``) or from a CSV path; a CSV path that ``traces`` (a run
    config's ``cycle_traces``: path -> {time_s: [...], speed_m_s: [...]}) holds is taken from there,
    not from the file, so a resolved config reproduces its run without the file."""
    key = str(name_or_path).strip()
    if traces and key in traces:
        return trace_cycle(key, traces[key])
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
    import difflib

    near = difflib.get_close_matches(key.lower(), CYCLE_NAMES, n=1, cutoff=0.6)
    raise ValueError(f"unknown drive cycle {key!r}: {f'did you mean {near[0]!r}? ' if near else ''}"
                     f"use one of {', '.join(CYCLE_NAMES)} or a CSV path")


@dataclass(frozen=True, eq=False)
class Resampled:
    """A cycle on a uniform grid with speed, acceleration and jerk from one interpolant."""

    name: str
    dt_s: float
    time_s: np.ndarray
    speed_m_s: np.ndarray
    accel_m_s2: np.ndarray
    jerk_m_s3: np.ndarray
    method: str = "pchip"

    @property
    def distance_m(self) -> float:
        """Trapezoid distance of the resampled speed."""
        return float(np.trapezoid(self.speed_m_s, self.time_s))

    def key(self) -> str:
        h = hashlib.sha1(f"{self.name}|{self.dt_s!r}|{self.method}".encode())
        for a in (self.time_s, self.speed_m_s, self.accel_m_s2, self.jerk_m_s3):
            h.update(np.ascontiguousarray(a, dtype=float).tobytes())
        return h.hexdigest()


_CACHE: dict[tuple, Resampled] = {}
METHODS = ("linear", "pchip", "spline")
DEFAULT_METHOD = "linear"
MAX_SAMPLES = 20_000_000
_GL2 = 0.5 / math.sqrt(3.0)  # two-point Gauss-Legendre nodes at the step centre +- h/(2 sqrt 3)


def resample(cycle: DriveCycle, dt_s: float = 1.0, method: str = DEFAULT_METHOD,
             smoothing: float | None = None) -> Resampled:
    """Resample ``cycle`` every ``dt_s`` seconds. ``linear`` (default) keeps the trace piecewise
    linear: the grid is every ``dt_s`` plus every breakpoint of the trace (so the grid may be
    non-uniform; ``dt_s`` is then the largest step), speeds are the trace's own, the
    acceleration at a grid point is the slope of the step that starts there and the jerk is
    zero. ``pchip`` is a shape-preserving cubic, ``spline`` a smoothing cubic spline (thesis
    §6.3.3; ``smoothing`` is the penalty lambda, None = chosen by generalised cross-validation).
    Results are cached."""
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
    if n + len(cycle.time_s) > MAX_SAMPLES:
        raise ValueError(f"drive cycle {cycle.name}: {cycle.duration_s:g} s at dt_s = {dt_s:g} s needs "
                         f"{n + 1} samples (at most {MAX_SAMPLES}); use a larger dt_s")
    t = t0 + dt_s * np.arange(n + 1)
    if method == "linear":
        t = np.sort(np.concatenate([t, cycle.time_s]))
        t = t[np.concatenate([[True], np.diff(t) > 1e-9 * max(1.0, dt_s)])]  # merge duplicates and float near-duplicates
        t[-1] = max(t[-1], cycle.time_s[-1])
        v = np.interp(t, cycle.time_s, cycle.speed_m_s)
        a = np.append(np.diff(v) / np.diff(t), 0.0)
        out = Resampled(cycle.name, float(dt_s), t, v, a, np.zeros_like(v), "linear")
    else:
        from scipy.interpolate import PchipInterpolator, make_smoothing_spline  # ~1-2 s to import: only here

        if method == "pchip":
            f = PchipInterpolator(cycle.time_s, cycle.speed_m_s, extrapolate=False)
        else:
            f = make_smoothing_spline(cycle.time_s, cycle.speed_m_s, lam=smoothing)
        d1, d2 = f.derivative(1), f.derivative(2)
        out = Resampled(cycle.name, float(dt_s), t, np.asarray(f(t), float),
                        np.asarray(d1(t), float), np.asarray(d2(t), float), method)
    for arr in (out.time_s, out.speed_m_s, out.accel_m_s2, out.jerk_m_s3):
        arr.setflags(write=False)
    if len(_CACHE) > 64:
        _CACHE.clear()
    _CACHE[key] = out
    return out


def quadrature(r: Resampled) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | float]:
    """Quadrature samples (speed, acceleration, jerk, weight in s) for integrating a cycle.

    ``linear``: two Gauss-Legendre points per step (exact for integrands up to cubic in time
    within a step, e.g. the wheel power F v with F = A + B v + C v^2); weights h/2.
    ``pchip``/``spline``: the grid points with weight ``dt_s`` (the thesis' rectangle sum,
    eq 7-27)."""
    if r.method != "linear":
        return r.speed_m_s, r.accel_m_s2, r.jerk_m_s3, r.dt_s
    h = np.diff(r.time_s)
    v0, v1 = r.speed_m_s[:-1], r.speed_m_s[1:]
    a = (v1 - v0) / h
    mid = 0.5 * (v0 + v1)
    v = np.stack([mid - a * h * _GL2, mid + a * h * _GL2], axis=1).reshape(-1)
    v = np.maximum(v, 0.0)
    return v, np.repeat(a, 2), np.zeros(2 * h.size), np.repeat(0.5 * h, 2)
