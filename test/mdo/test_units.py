"""Declared units (bev_mdo/mdo/units.py): a metre output feeding a kilometre input is converted, a
second refused at load in one line naming both ends, and tables print the declared units."""
from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

from bev_mdo.cli import main
from bev_mdo.config import load_config, resolve_disciplines
from bev_mdo.mdo.discipline import run_discipline
from bev_mdo.mdo.units import UnitError, conversions, factor, run_units

# a trip (speed x time) gives the distance in the unit DIST; the fuel discipline reads it in km
MODULE = '''
class Trip:
    name = "trip"
    inputs = ("speed_kmh", "time_h")
    outputs = ("dist",)
    units = {{"speed_kmh": "km/h", "time_h": "h", "dist": "{dist}"}}

    def compute(self, inputs):
        return {{"dist": inputs["speed_kmh"] * inputs["time_h"] * {scale}}}


class Fuel:
    name = "fuel"
    inputs = ("dist", "time_h")
    outputs = ("fuel_l", "mass_kg")
    units = {{"dist": "km", "time_h": "h", "fuel_l": "l", "mass_kg": "lb"}}

    def compute(self, inputs):
        return {{"fuel_l": 0.06 * inputs["dist"] + inputs["time_h"], "mass_kg": 2.0 * inputs["dist"]}}

    def compute_partials(self, inputs):
        n = len(inputs["dist"])
        return {{("fuel_l", "dist"): np.full(n, 0.06), ("fuel_l", "time_h"): np.ones(n),
                 ("mass_kg", "dist"): np.full(n, 2.0)}}
'''


def _config(tmp_path, module: str, dist: str, scale: str):
    folder = tmp_path / module
    folder.mkdir()
    (folder / f"{module}.py").write_text("import numpy as np\n" + MODULE.format(dist=dist, scale=scale))
    raw = {"name": module, "search_path": [str(folder)],
           "disciplines": [{"name": "trip", "class": f"{module}:Trip"}, {"name": "fuel", "class": f"{module}:Fuel"}],
           "problem": {"objective": "fuel_l",
                       "design_variables": {"speed_kmh": {"lower": 10, "upper": 130, "initial": 87.5},
                                            "time_h": {"lower": 0.1, "upper": 5, "initial": 1.75}},
                       "constraints": {"dist": {"upper": 1e9}}},
           "formulation": "mdf", "mda": {"method": "gauss_seidel", "tolerance": 1e-12, "max_iterations": 10,
                                          "relaxation": 1.0},
           "optimizer": {"name": "SLSQP", "options": {}, "fd_step": 1e-7}}
    path = tmp_path / f"{module}.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


def _evaluate(capsys, path):
    assert main(["evaluate", str(path), "--json", "--transport", "inprocess"]) == 0
    return json.loads(capsys.readouterr().out)


def test_metres_into_kilometres_are_converted_and_give_the_all_km_result(tmp_path, capsys):
    metres = _config(tmp_path, "trip_m", "m", "1000.0")
    km = _config(tmp_path, "trip_km", "km", "1.0")
    got, ref = _evaluate(capsys, metres), _evaluate(capsys, km)
    assert got["outputs"]["dist"] == pytest.approx(1000.0 * 87.5 * 1.75, rel=1e-15)  # the producer's metres
    assert ref["outputs"]["dist"] == pytest.approx(87.5 * 1.75, rel=1e-15)
    # fuel read the distance in km in both runs: 0.06 x 153.125 km + 1.75 h
    assert got["outputs"]["fuel_l"] == pytest.approx(ref["outputs"]["fuel_l"], rel=1e-12)
    assert got["outputs"]["fuel_l"] == pytest.approx(0.06 * 153.125 + 1.75, rel=1e-12)
    # only the consumer of the metres is converted, by 1/1000, once
    discs = resolve_disciplines(load_config(metres))
    assert conversions(discs) == {"fuel": {"dist": (pytest.approx(1e-3, rel=1e-15), 0.0)}}
    assert run_units(discs)["dist"] == "m" and not conversions(resolve_disciplines(load_config(km)))


def test_the_partials_of_a_converted_input_are_per_unit_of_the_producer(tmp_path):
    fuel = {d.name: d for d in resolve_disciplines(load_config(_config(tmp_path, "trip_p", "m", "1000.0")))}["fuel"]
    res = run_discipline(fuel, {"dist": np.array([2000.0, 5000.0]), "time_h": np.array([1.0, 2.0])}, partials=True)
    np.testing.assert_allclose(res.outputs["fuel_l"], [0.06 * 2 + 1, 0.06 * 5 + 2], rtol=1e-14)
    part = res.extra["partials"]
    np.testing.assert_allclose(part[("fuel_l", "dist")], [0.06e-3, 0.06e-3], rtol=1e-14)  # d fuel / d metre
    np.testing.assert_allclose(part[("fuel_l", "time_h")], [1.0, 1.0])  # not converted


def test_seconds_into_kilometres_are_refused_at_load_in_one_line(tmp_path, capsys):
    path = _config(tmp_path, "trip_s", "s", "1.0")
    assert main(["evaluate", str(path), "--transport", "inprocess"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert "trip.dist [s] -> fuel.dist [km]" in err and "different dimensions" in err


def test_a_variable_without_a_unit_is_refused_at_load(tmp_path, capsys):
    path = _config(tmp_path, "trip_none", "km", "1.0")
    mod = tmp_path / "trip_none" / "trip_none.py"
    mod.write_text(mod.read_text().replace('"mass_kg": "lb"', ""))
    assert main(["evaluate", str(path), "--transport", "inprocess"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "disciplines[1] (fuel): no unit declared for ['mass_kg']" in err


def test_table_units_come_from_the_declarations_not_the_names(tmp_path, capsys):
    """mass_kg is declared in lb, dist in m: the compare table prints those, whatever the names say."""
    path = _config(tmp_path, "trip_t", "m", "1000.0")
    assert main(["compare", str(path), "--design", "speed_kmh=50", "--design", "speed_kmh=60",
                 "--transport", "inprocess"]) == 0
    rows = {line.split("│")[1].strip(): line.split("│")[2].strip()
            for line in capsys.readouterr().out.splitlines() if line.count("│") > 3}
    assert rows["mass_kg"] == "lb" and rows["dist"] == "m" and rows["fuel_l"] == "l"
    assert rows["speed_kmh"] == "km/h" and rows["time_h"] == "h"


def test_factor_and_its_errors():
    assert factor("m", "km") == (pytest.approx(1e-3), 0.0)
    assert factor("Wh/km", "Wh/km") == (1.0, 0.0)
    scale, offset = factor("degC", "K")
    assert (scale, offset) == (pytest.approx(1.0), pytest.approx(273.15))
    assert factor("1", "") == (1.0, 0.0)
    with pytest.raises(UnitError, match="different dimensions"):
        factor("s", "km")
    with pytest.raises(UnitError, match="not a unit pint knows"):
        factor("furlongs_per_fortnight_x", "m")


class _Heat:
    name, inputs, outputs = "thermal", ("h",), ("dT",)

    def __init__(self, unit):
        self.units = {"h": "W/K", "dT": unit}


class _Cost:
    name, inputs, outputs = "econ", ("dT",), ("cost",)

    def __init__(self, unit):
        self.units = {"dT": unit, "cost": "USD"}


@pytest.mark.parametrize("made, read", [("K", "degC"), ("degC", "K"), ("degF", "degC")])
def test_a_connection_that_needs_an_offset_is_refused(made, read):
    """A user trial: a temperature rise produced in K and read in degC was shifted by 273.15 (cost -1000.03 for
    92.57, 'feasible', 'optimum'): an offset unit converts as an absolute temperature, which a rise is not."""
    with pytest.raises(UnitError, match=rf"thermal.dT \[{made}\] -> econ.dT \[{read}\] \(an offset unit.*delta_degC"):
        conversions([_Heat(made), _Cost(read)])


def test_a_temperature_difference_in_delta_degc_is_converted_by_scale_alone():
    assert conversions([_Heat("K"), _Cost("delta_degC")]) == {}
    assert conversions([_Heat("K"), _Cost("delta_degF")]) == {"econ": {"dT": (pytest.approx(1.8), 0.0)}}
    assert conversions([_Heat("degC"), _Cost("degC")]) == {}  # the same unit at both ends: nothing to convert
    # a difference read as a temperature: one line naming both ends (it was pint's DimensionalityError, raw)
    with pytest.raises(UnitError, match=r"thermal.dT \[delta_degC\] -> econ.dT \[degC\] \(delta_degC does not convert"):
        conversions([_Heat("delta_degC"), _Cost("degC")])
