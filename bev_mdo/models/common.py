"""Ground floor of the models: input checks shared by every model, and the one table of design limits.

Imports nothing from the package (numpy only), so every model module may import it.

* :func:`check_value` / :func:`check_array`: a float or array in a closed range, one-line ValueError.
* :data:`DESIGN_LIMITS` and :func:`check_design` / :func:`design_points`: the physical ranges of the
  design and coupling variables every model accepts.
* :func:`resolve_params` / :func:`batch_size`: defaults from a spec table (``params.py``), range
  checks, and the common batch length N of design arrays and (N,) parameter overrides
  (:func:`check_lengths`: arrays of other lengths are a one-line error naming each and its shape).
* A complex value is refused (a ValueError naming it), except by :func:`check_points` and
  :func:`resolve_params` without ``real``, which keep it for the model differentiated by complex
  step (breakdown).
* :func:`check_keys`: a mapping's keys against the known ones; the message names the key path and
  the nearest known key (every config section and option dictionary uses it).
* :func:`text_hint`: where a config expects a number and finds text that reads as one (``2e2``, a
  quoted ``"1134"``), why YAML gave text and what to write. Such text is refused everywhere.
"""
from __future__ import annotations

import math
import re
from typing import Any, Mapping

import numpy as np

# Physical ranges (lower, upper, unit) of the design and coupling variables the models accept. The energy
# has no upper limit: a design that cannot follow the cycle may cost any finite energy (the chain's copper
# loss grows with the square of the demand over the motor's peak torque), and its range is then near
# zero, an infeasible point for the optimiser; at 5000 Wh/km the range refused it and the point failed.
# Nor has the battery: with ``battery_sized_for_range`` it is a result (eq 7-28 inverted), and a 2000 km
# target on leaf_nedc.yaml sizes 598 kWh, a 6.1 t car that takes 41 s to 100 km/h: an infeasible point, which
# a 500 kWh limit here turned into a failed one. Its limit is the one the vehicle mass limit implies at the
# lightest battery_kg_per_kwh accepted (20 000 kg / 0.5 kg/kWh): a larger battery never gives a mass the
# models accept, and a bound far above it left the optimiser (which scales each variable to its bounds)
# stalled at its start (30-1e6 kWh on a Bolt config: 'infeasible').
DESIGN_LIMITS: dict[str, tuple[float, float, str]] = {
    "motor_kw": (1.0, 1000.0, "kW"),
    "motor_rear_kw": (1.0, 1000.0, "kW"),
    "gear_ratio": (0.5, 50.0, "-"),
    "gear_ratio_rear": (0.5, 50.0, "-"),
    "battery_kwh": (1.0, 40000.0, "kWh"),
    "vehicle_mass_kg": (100.0, 20000.0, "kg"),
    "energy_wh_per_km": (1.0, math.inf, "Wh/km"),
    "range_target_km": (1.0, 10000.0, "km"),
}


# keys a user brings from a data sheet that stand for a factor of one of ours: the product is wanted, not the name
# (frontal_area_m2 was told "did you mean 'drag_area_m2'?", and a 500e with 2.1 m^2 as Cd A used 2.2x its energy)
_DRAG_AREA = ("drag_area_m2", "Cd x frontal area, m^2 (e.g. 0.29 x 2.27 m^2 = 0.658)")
PRODUCT_KEYS = {k: _DRAG_AREA for k in ("frontal_area_m2", "frontal_area", "drag_coefficient", "cd", "cx", "cw")}


def name_hint(name: Any, known, cutoff: float = 0.6) -> str:
    """The hint after an unknown ``name``: ``did you mean 'x'? `` for a known name in another case or the nearest
    by difflib; where ``name`` is a factor of a known product (``PRODUCT_KEYS``) and no other known name is nearer,
    ``'drag_area_m2' is Cd x frontal area, ...: give the product; ``; else ""."""
    import difflib

    names, typed = sorted(map(str, known)), str(name).lower()
    # the same name in another case, or with a unit: a user's own Cd or frontal_area_m2, nearer than any product
    same = [k for k in names if k.lower() == typed or k.lower().startswith(typed + "_")]
    want = PRODUCT_KEYS.get(typed)
    if want and want[0] in names and not same:
        return f"{want[0]!r} is {want[1]}: give the product; "
    near = same or difflib.get_close_matches(str(name), names, n=1, cutoff=cutoff)
    return f"did you mean {near[0]!r}? " if near else ""


def check_keys(where: str, given: Any, known: Any, of: str = "") -> None:
    """One-line ValueError for the first key of ``given`` not in ``known``: ``<where>.<key>: unknown
    key; did you mean '<nearest>'? known: ...`` (nearest by difflib). ``where`` is the key path of
    the mapping, e.g. ``disciplines[1] (energy).options`` ("" for the top level); ``of`` names whose
    keys they are (``unknown key of SLSQP``)."""
    names = sorted(str(k) for k in known)
    for key in given:
        if key in known:
            continue
        hint = name_hint(key, names)
        listed = f"known: {', '.join(names)}" if names else "none is declared"
        raise ValueError(f"{where + '.' if where else ''}{key}: unknown key{' of ' + of if of else ''}; {hint}{listed}")


_EXPONENT_WITHOUT_DOT_OR_SIGN = re.compile(r"([-+]?[0-9][0-9_]*)(\.[0-9_]*)?[eE]([-+]?)([0-9]+)")


def text_hint(value: Any) -> str:
    """`` (why YAML read it as text: what to write)`` for a config value that is text but reads as a
    number, else "". PyYAML reads YAML 1.1, whose floats need a dot and a signed exponent: ``2e2`` and
    ``2.0e2`` are text, ``2.0e+2`` is 200.0; a quoted number is text in any YAML. Text is refused where a
    number is expected (float() took "1134" in one section and not in another)."""
    if not isinstance(value, str):
        return ""
    text = value.strip()
    try:
        x = float(text)
    except ValueError:
        return comma_hint(text)
    if not math.isfinite(x):
        return " (text; YAML's infinity is .inf)" if "inf" in text.lower() else ""
    m = _EXPONENT_WITHOUT_DOT_OR_SIGN.fullmatch(text)
    if m and not (m.group(2) and m.group(3)):  # a dot and a signed exponent: a YAML float, so it was quoted
        plain = np.format_float_positional(x, trim="-")
        mantissa = m.group(1) + (m.group(2) if m.group(2) and m.group(2) != "." else ".0")
        written = f"{mantissa}e{m.group(3) or '+'}{m.group(4)}"
        return f" (YAML reads {text} as text: write {written}" + (f" or {plain})" if len(plain) <= 10 else ")")
    return f" (text, not a number: write {text} without quotes)"


def comma_hint(text: str) -> str:
    """`` (a decimal comma? write 7.94)`` for text that is a number with one comma for its point, else ""; where
    three digits follow the comma, it may group thousands too (``1,269``: 1.269 or 1269)."""
    head, _, tail = text.partition(",")
    if not (head.lstrip("+-").isdigit() and tail.isdigit()):
        return ""
    return f" (a decimal comma? write {head}.{tail}" + (f"; or {head}{tail} if it groups thousands)" if len(tail) == 3
                                                         else ")")


def is_number(value: Any) -> bool:
    """A real number as YAML gives one (int or float, numpy's too): not a bool, not text."""
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


def check_whole(value: Any) -> int:
    """A whole number (an int or a numpy integer; not a bool, which Python counts as 1, nor 2.9 or "3", which
    int() would take); ValueError otherwise. Every count and seed of the Python API."""
    if not isinstance(value, (int, np.integer)) or isinstance(value, (bool, np.bool_)):
        if isinstance(value, (float, np.floating)) and float(value).is_integer():  # 16.0 'not a whole number'
            raise ValueError(f"{value!r} is a float: give it as an int ({int(value)})")
        raise ValueError(f"{value!r} is not a whole number")
    return int(value)


def check_seed(value: Any) -> int:
    """A random seed: a whole number >= 0 (numpy refuses a negative one with "expected non-negative integer",
    which names nothing, and takes True as 1); ValueError otherwise. ``--seed`` and the Python API's seed."""
    check_whole(value)
    if value < 0:
        raise ValueError(f"{value}: give a whole number >= 0")
    return int(value)


def _unit(unit: str) -> str:
    return f" {unit}" if unit and unit != "-" else ""


def allowed(lower: float, upper: float, unit: str = "", integer: bool = False) -> str:
    """What a value must be, as error messages say it: ``in [0.5, 1]``, ``1 or 2``, ``an integer in [3, 101]``."""
    if integer and upper - lower <= 2:
        return " or ".join(f"{v:g}" for v in np.arange(lower, upper + 1))
    return f"{'an integer ' if integer else ''}in [{lower:g}, {upper:g}]{_unit(unit)}"


def check_value(name: str, value: Any, lower: float, upper: float, unit: str = "", integer: bool = False) -> float:
    """Return ``value`` as float; ValueError naming ``name`` and [lower, upper] otherwise (``integer``: a
    count or a switch, whole numbers only)."""
    if isinstance(value, (bool, np.bool_)):  # YAML's true is 1 to float(): glider_kg: true was read as 1 kg
        raise ValueError(f"{name} must be a number {allowed(lower, upper, unit, integer)}, got {str(value).lower()} (a bool)")
    if not is_number(value):  # float() took glider_kg: "1134" and 1134e0 (text), which a bound refused
        raise ValueError(f"{name} must be a number {allowed(lower, upper, unit, integer)}, got {value!r}"
                         f"{text_hint(value)}")
    x = float(value)
    if not (math.isfinite(x) and lower <= x <= upper) or (integer and x != round(x)):
        raise ValueError(f"{name} must be {allowed(lower, upper, unit, integer)}, got {x:g}")
    return x


def check_array(name: str, values: Any, lower: float, upper: float, unit: str = "") -> np.ndarray:
    """Vector form of :func:`check_value`: names the first bad element."""
    given = np.asarray(values)
    if given.dtype.kind not in "iuf":  # float() read True as 1 and "1500" as 1500, None as nan, 80+1j as 80
        _refuse(name, given, lower, upper, unit)
    a = np.asarray(values, dtype=float)
    if a.size == 1:  # one design point (an MDA over ROS, a line search): ~0.3 µs instead of ~4.5
        x = a.item()
        if math.isfinite(x) and lower <= x <= upper:
            return a
    bad = ~(np.isfinite(a) & (a >= lower) & (a <= upper))
    if bad.any():
        first = a.reshape(-1)[np.flatnonzero(bad.reshape(-1))[0]]
        raise ValueError(f"{name} must be in [{lower:g}, {upper:g}]{_unit(unit)}, got {first:g}")
    return a


def _refuse(name: str, given: np.ndarray, lower: float, upper: float, unit: str) -> None:
    """The one-line ValueError for a value that is not a real number: a bool, string, object or complex."""
    kind = given.dtype.kind
    what = {"b": "bools", "U": "strings", "S": "bytes", "c": "complex numbers"}.get(kind, "objects")
    shown = repr(given.reshape(-1).tolist()[0]) if given.size == 1 else f"an array of {what}"
    shown += " (complex)" if kind == "c" and given.size == 1 else ""
    raise ValueError(f"{name} must be a {'real ' if kind == 'c' else ''}number in [{lower:g}, {upper:g}]{_unit(unit)}, "
                     f"got {shown}")


def check_lengths(**arrays: Any) -> int:
    """N: the common length of the 1-D arrays given by name (a scalar or a single value goes with any N);
    when they disagree, a one-line ValueError naming each array and its shape (numpy's broadcast message
    named neither)."""
    n = 1
    for a in arrays.values():  # one design point: floats and (1,) arrays, a few hundred ns
        if type(a) is float:
            continue
        k = a.size if type(a) is np.ndarray and a.ndim == 1 else np.size(a) if np.ndim(a) == 1 else 1
        if k != 1 and k != n:
            if n != 1:
                shapes = ", ".join(f"{name} {np.shape(x)}" for name, x in arrays.items()
                                   if type(x) is not float and np.ndim(x) == 1 and np.size(x) != 1)
                raise ValueError(f"arrays of different lengths: {shapes}; give one length N (or a single value)")
            n = k
    return n


def validate_design(name: str, values: Any, lower: float, upper: float, unit: str = "") -> np.ndarray:
    """Design-variable array check: a number or 1-D batch, finite and within [lower, upper] ``unit``,
    ValueError naming it and the unit."""
    if np.ndim(values) > 1:  # a batch is one axis: a (2, 2) battery gave a (2, 2) range
        raise ValueError(f"{name} must be a number or a 1-D array, got shape {np.shape(values)}")
    return check_array(name, np.atleast_1d(values), lower, upper, unit)


def check_design(name: str, values: Any) -> np.ndarray:
    """Check a design or coupling variable against :data:`DESIGN_LIMITS` (a float array, at least 1-D)."""
    lo, hi, unit = DESIGN_LIMITS[name]
    if type(values) is np.ndarray and values.ndim == 1 and values.size == 1 and values.dtype == _F64:
        x = values.item()  # one design point (an MDA over ROS): the same array back, checked
        if math.isfinite(x) and lo <= x <= hi:
            return values
    return validate_design(name, values, lo, hi, unit)


_F64 = np.dtype(np.float64)


def check_points(name: str, values, lower: float, upper: float, unit: str) -> np.ndarray:
    """A design/coupling batch as a 1-D array (complex kept), range-checked on its real part."""
    a = np.atleast_1d(np.asarray(values))
    if a.ndim != 1 or a.dtype.kind not in "iufc":  # a bool is not a design value (True was a ratio of 1)
        raise ValueError(f"{name} must be a number or 1-D array in [{lower:g}, {upper:g}] {unit}")
    re = np.real(a).astype(float)
    bad = ~(np.isfinite(re) & (re >= lower) & (re <= upper))
    if bad.any():
        raise ValueError(f"{name} must be in [{lower:g}, {upper:g}] {unit}, got {re[bad][0]:g}")
    return a if a.dtype.kind == "c" else a.astype(float)


def design_points(name: str, values, *, real: bool = False) -> np.ndarray:
    """:func:`check_points` with the limits of :data:`DESIGN_LIMITS`; ``real``: a real model, which refuses
    a complex value (it dropped the imaginary part without a word)."""
    a = check_points(name, values, *DESIGN_LIMITS[name])
    if real and a.dtype.kind == "c":
        _refuse(name, a, *DESIGN_LIMITS[name])
    return a


def resolve_params(params: Mapping[str, Any] | None, specs: Mapping[str, Any], n: int, *,
                   real: bool = False) -> dict[str, np.ndarray]:
    """Fill defaults from ``specs`` (name -> ParamSpec) and range-check; values stay scalars or (n,)
    arrays (complex allowed, unless ``real``: a real model refuses one). Names not in ``specs`` are
    ignored (a params dict may carry other models' constants)."""
    params = params or {}
    out = {}
    for name, s in specs.items():
        v = params.get(name, s.default)
        try:
            a = np.asarray(v)
            if a.dtype.kind not in "iufc":  # a bool is not a parameter value (drag_area_m2: True was 1 m^2)
                raise TypeError
        except TypeError:
            raise ValueError(f"{name} must be a number {allowed(s.lower, s.upper, s.unit, s.integer)}, got {v!r}") from None
        if a.ndim > 1 or (a.ndim == 1 and a.shape[0] not in (1, n)):
            raise ValueError(f"{name} must be a scalar or an array of shape ({n},), got shape {a.shape}")
        re = np.real(a).astype(float)
        bad = ~(np.isfinite(re) & (re >= s.lower) & (re <= s.upper))
        if s.integer:  # a count or a switch
            bad |= re != np.round(re)
        if a.dtype.kind == "c":
            bad |= ~np.isfinite(np.imag(a))
        if bad.any():
            x = re.reshape(-1)[np.flatnonzero(bad.reshape(-1))[0]]
            raise ValueError(f"{name} must be {allowed(s.lower, s.upper, s.unit, s.integer)}, got {x:g}")
        if real and a.dtype.kind == "c":  # the real models dropped the imaginary part without a word
            _refuse(name, a, s.lower, s.upper, s.unit)
        out[name] = a if a.dtype.kind == "c" else a.astype(float)
    return out


def batch_size(params: Mapping[str, Any] | None, specs, **arrays) -> int:
    """N: the common length of the design arrays (by name) and any (N,) parameter overrides (:func:`check_lengths`)."""
    return check_lengths(**arrays, **{k: params[k] for k in specs if params and k in params and k not in arrays})


class LazyModule:
    """The module ``name``, imported on its first attribute access: the compiled loops' numba import and
    cache load (0.7 s) are paid only by a process that runs them, not by one that imports the models and
    runs their numpy passes (``bev-mdo validate``). Each access goes through importlib (a dictionary
    lookup once imported), whose import lock makes a first access from two threads safe."""

    def __init__(self, name: str):
        self._name = name

    def __getattr__(self, attr: str):
        import importlib

        return getattr(importlib.import_module(self._name), attr)
