"""Declared units: every input and output of a discipline names its unit, checked and converted at load.

A discipline declares ``units = {variable: unit}`` for each of its inputs and outputs (a vector by
its base name: ``{"x_shared": "1"}``), in pint's syntax: ``"kW"``, ``"Wh/km"``, ``"rad/s"``,
``"N*m"``, ``"USD"``; ``"1"`` (or ``""``) for a dimensionless variable. A variable no unit is
declared for is refused at load (:func:`check_declared`).

A variable's unit in the run (tables, plots, constraint bounds) is its producer's; an input no
discipline produces (a design variable) has the unit of its first consumer in the disciplines'
order. A consumer that declares another unit of the same dimension gets the value converted on
entry (:func:`conversions`, applied by ``discipline.run_discipline`` on every transport); a unit
of another dimension is an error at load naming both ends, and so is a connection that would need an
offset (K to degC): a temperature difference declared in degC would be shifted by 273.15. pint is used
here, once, at load: the hot path multiplies numpy arrays by a float.
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping
from functools import lru_cache
from typing import Any

from bev_mdo.mdo.vectors import base_name

DIMENSIONLESS = ("", "1", "-")

# display names of built-in variables (the unit always comes from the declaration)
_QUANTITY = {
    "energy_wh_per_km": "battery energy",
    "energy_wall_wh_per_km": "wall energy",
    "range_km": "range",
    "accel_time_0_100_s": "0–100 km/h time",
    "motor_speed_max_rad_s": "max motor speed",
    "powertrain_cost_usd": "powertrain cost",
    "vehicle_mass_kg": "vehicle mass",
    "motor_kw": "motor power",
    "motor_rear_kw": "rear motor power",
    "battery_kwh": "battery capacity",
    "gear_ratio": "gear ratio",
    "gear_ratio_rear": "rear gear ratio",
    "top_speed_kmh": "top speed",
    "max_violation": "max constraint violation",
}


class UnitError(ValueError):
    """A unit that cannot be parsed, is missing, or a connection of units of different dimensions."""


@lru_cache(maxsize=1)
def _registry():
    import pint

    reg = pint.UnitRegistry()
    reg.define("USD = [currency] = US$")  # pint has no currencies; cost is its own dimension
    return reg


@lru_cache(maxsize=512)
def _parse(unit: str):
    text = unit.strip()
    if text in DIMENSIONLESS:
        return _registry().dimensionless
    try:
        return _registry().parse_units(text)
    except Exception as exc:  # pint's own errors (UndefinedUnitError, syntax): one line
        raise UnitError(f"unit {unit!r} is not a unit pint knows ({type(exc).__name__})") from None


def check_unit(unit: Any, where: str) -> str:
    """The declared unit as a string; UnitError naming ``where`` when it is not one."""
    if not isinstance(unit, str):
        raise UnitError(f"{where}: unit must be a string such as 'kW' or '1', got {unit!r}")
    try:
        _parse(unit)
    except UnitError as exc:
        raise UnitError(f"{where}: {exc}") from None
    return unit.strip()


def declared(disc: Any) -> dict[str, str]:
    """{variable: unit} of a discipline's inputs and outputs (vector elements take their base's)."""
    units = getattr(disc, "units", None) or {}
    out = {}
    for v in (*disc.inputs, *disc.outputs):
        u = units.get(v, units.get(base_name(v)))
        if u is not None:
            out[v] = u
    return out


def check_declared(disc: Any, where: str) -> dict[str, str]:
    """The declared units of every input and output; UnitError naming the variables without one."""
    units = getattr(disc, "units", None)
    if units is not None and not isinstance(units, Mapping):
        raise UnitError(f"{where}: units must be a mapping {{variable: unit}}, got {type(units).__name__}")
    got = declared(disc)
    missing = [v for v in (*disc.inputs, *disc.outputs) if v not in got]
    if missing:
        names = list(dict.fromkeys(base_name(v) for v in missing))
        raise UnitError(f"{where}: no unit declared for {names}; give the discipline units = "
                        f"{{'{names[0]}': ..., ...}} (a unit such as 'kW', or '1' for a dimensionless variable)")
    return {v: check_unit(u, f"{where}.units.{base_name(v)}") for v, u in got.items()}


def run_units(disciplines: Iterable[Any]) -> dict[str, str]:
    """{variable: its unit in the run}: the producer's, else the first consumer's."""
    discs = list(disciplines)
    out: dict[str, str] = {}
    for d in discs:
        u = declared(d)
        out.update({v: u[v] for v in d.outputs if v in u})
    for d in discs:
        u = declared(d)
        for v in d.inputs:
            if v not in out and v in u:
                out[v] = u[v]
    return out


def factor(source: str, target: str) -> tuple[float, float]:
    """(scale, offset) turning a value in ``source`` into ``target``: y = scale x + offset.
    UnitError when the two units have different dimensions."""
    a, b = _parse(source), _parse(target)
    if a == b:
        return 1.0, 0.0
    if a.dimensionality != b.dimensionality:
        raise UnitError(f"{source.strip() or '1'} and {target.strip() or '1'} have different dimensions")
    import pint

    q = _registry().Quantity
    try:
        zero, one = q(0.0, a).to(b).magnitude, q(1.0, a).to(b).magnitude
    except pint.errors.PintError as exc:  # delta_degC -> degC: a difference is no temperature
        raise UnitError(f"{source.strip()} does not convert to {target.strip()} ({type(exc).__name__}: a temperature "
                        "difference and an absolute temperature)") from None
    return float(one - zero), float(zero)


def conversions(disciplines: Iterable[Any]) -> dict[str, dict[str, tuple[float, float]]]:
    """{discipline: {input: (scale, offset)}} for every input whose declared unit differs from the
    variable's unit in the run; UnitError (one line) for a connection of different dimensions:
    ``producer.output [unit] -> consumer.input [unit]``."""
    discs = list(disciplines)
    run = run_units(discs)
    source = {v: d.name for d in discs for v in d.outputs}
    out: dict[str, dict[str, tuple[float, float]]] = {}
    for d in discs:
        mine = declared(d)
        for v in d.inputs:
            if v not in mine or v not in run or mine[v] == run[v]:
                continue
            try:
                scale, offset = factor(run[v], mine[v])
            except UnitError as exc:
                first = source.get(v) or next(c.name for c in discs if v in c.inputs)
                raise UnitError(f"units do not match: {first}.{base_name(v)} [{run[v]}] -> {d.name}.{base_name(v)} "
                                f"[{mine[v]}] ({exc})") from None
            if offset != 0.0:  # K -> degC takes 273.15 off an absolute temperature, and a rise is no temperature
                first = source.get(v) or next(c.name for c in discs if v in c.inputs)
                raise UnitError(f"units do not match: {first}.{base_name(v)} [{run[v]}] -> {d.name}.{base_name(v)} "
                                f"[{mine[v]}] (an offset unit: it would convert as an absolute temperature, shifted "
                                f"by {abs(offset):g}; declare the same unit at both ends, or delta_degC / delta_degF "
                                "for a temperature difference)")
            if (scale, offset) != (1.0, 0.0):
                out.setdefault(d.name, {})[v] = (scale, offset)
    return out


def attach_units(discs: list, where: list[str]) -> list:
    """Check the declared units of a run's disciplines (``where``: how each is named in the config)
    and set ``unit_conversions`` on each consumer that needs one (applied by run_discipline)."""
    for d, w in zip(discs, where):
        check_declared(d, w)
    for name, conv in conversions(discs).items():
        d = next(d for d in discs if d.name == name)
        try:
            d.unit_conversions = conv
        except AttributeError:
            raise UnitError(f"discipline {name!r}: cannot set its unit conversions (a read-only attribute)") from None
    return discs


def shown(unit: str) -> str:
    """A unit as printed in tables and on axes ('–' for dimensionless)."""
    return "–" if unit.strip() in DIMENSIONLESS else unit.strip()


def unit_of(name: str, units: Mapping[str, str], inline: bool = False) -> str:
    """The declared unit of a variable as printed ('' when it is not a variable of the run). ``inline``:
    after a number in a sentence, where a dimensionless quantity has none ('–' read as a minus sign)."""
    u = units.get(name)
    return "" if u is None or (inline and u.strip() in DIMENSIONLESS) else shown(u)


def label(name: str, units: Mapping[str, str]) -> str:
    """Axis label: quantity and declared unit, e.g. ``battery energy (Wh/km)``; ``gear ratio (–)``."""
    q = _QUANTITY.get(name, name)
    u = unit_of(name, units)
    return f"{q} ({u})" if u else q
