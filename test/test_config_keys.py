"""A key a config does not declare is refused when the config is loaded: one line on stderr naming the
file, the key path and the nearest declared key (difflib), exit 2 (docs/user-problems.md, Options)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
import sys

import pytest
import yaml

from bev_mdo.cli import main
from bev_mdo.config import load_config
from bev_mdo.testing import REPO

EPA = REPO / "config" / "leaf_epa_combined.yaml"
NEDC = REPO / "config" / "leaf_nedc.yaml"


def _write(tmp_path: Path, text: str, name: str = "c.yaml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def _cli(capsys, *argv) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_a_misspelt_builtin_option_exits_2_naming_file_key_and_suggestion(tmp_path, capsys):
    text = EPA.read_text()
    assert "cycle_weights:" in text
    cfg = _write(tmp_path, text.replace("cycle_weights:", "cycle_weigths:"))
    for argv in (("optimize", cfg, "--transport", "inprocess"), ("optimize", cfg),  # ROS: refused at load
                 ("evaluate", cfg, "--transport", "inprocess")):
        code, out, err = _cli(capsys, *argv)
        assert code == 2, argv
        assert out == "" and len(err.strip().splitlines()) == 1, err
        assert f"{cfg}: disciplines[1] (energy).options.cycle_weigths: unknown key; did you mean " \
               "'cycle_weights'?" in err


def test_an_unknown_optimizer_option_exits_2_with_the_suggestion(tmp_path, capsys):
    cfg = _write(tmp_path, NEDC.read_text().replace("optimizer: {name: SLSQP, options: {}",
                                                    "optimizer: {name: SLSQP, options: {maxitr: 5}"))
    assert "maxitr" in cfg.read_text()
    code, out, err = _cli(capsys, "optimize", cfg, "--transport", "inprocess")
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, err
    assert f"{cfg}: optimizer.options.maxitr: unknown key of SLSQP; did you mean 'maxiter'?" in err


@pytest.mark.parametrize("optimizer,bad,near", [("COBYLA", "rhobegn", "rhobeg"), ("trust-constr", "gtoll", "gtol"),
                                                ("chebyshev-pairwise", "maxiters", "maxiter")])
def test_every_optimizer_checks_its_options(tmp_path, optimizer, bad, near):
    raw = yaml.safe_load(NEDC.read_text())
    raw["optimizer"] = {"name": optimizer, "options": {bad: 1}}
    with pytest.raises(ValueError, match=rf"optimizer.options.{bad}: unknown key of {optimizer}; did you mean '{near}'"):
        load_config(raw)


@pytest.mark.parametrize("section,edit,path,near", [
    ("vehicle", lambda r: r["vehicle"].update(drag_aera_m2=0.7), "vehicle.drag_aera_m2", "drag_area_m2"),
    ("cycle", lambda r: r["cycle"].update(interpolaton="linear"), "cycle.interpolaton", "interpolation"),
    ("mda", lambda r: r["mda"].update(tolerence=1e-9), "mda.tolerence", "tolerance"),
    ("optimizer", lambda r: r["optimizer"].update(fd_stp=1e-6), "optimizer.fd_stp", "fd_step"),
    ("problem", lambda r: r["problem"].update(constraint={}), "problem.constraint", "constraints"),
    ("design variable", lambda r: r["problem"]["design_variables"]["motor_kw"].update(lowr=40),
     "problem.design_variables.motor_kw.lowr", "lower"),
    ("constraint", lambda r: r["problem"]["constraints"]["range_km"].update(lowwer=1),
     "problem.constraints.range_km.lowwer", "lower"),
    ("top level", lambda r: r.update(optimiser={}), "optimiser", "optimizer"),
    ("ros", lambda r: r.update(ros={"domain": 3}), "ros.domain", "domain_id"),
])
def test_every_section_names_the_key_path_and_the_nearest_key(section, edit, path, near):
    raw = yaml.safe_load(NEDC.read_text())
    edit(raw)
    with pytest.raises(ValueError, match=rf"^<config>: {path}: unknown key; did you mean '{near}'\?"):
        load_config(raw)


def test_options_of_a_discipline_without_options_are_refused():
    raw = yaml.safe_load(NEDC.read_text())
    raw["disciplines"] = ["vehicle_mass", "energy", {"name": "range", "options": {"usable": 0.9}},
                          "acceleration", "motor_speed", "cost"]
    with pytest.raises(ValueError, match=r"disciplines\[2\] \(range\).options.usable: unknown key; none is declared"):
        load_config(raw)
    raw["disciplines"][2] = "range"
    raw["recording"] = {"compress": True}
    with pytest.raises(ValueError, match=r"recording.compress: unknown key"):
        load_config(raw)


USER = '''
from dataclasses import dataclass

import numpy as np


class Declared:
    """A user discipline declaring its options in a dataclass."""

    name = "declared"
    inputs = ("x",)
    outputs = ("y",)
    units = {"x": "1", "y": "1"}

    @dataclass(frozen=True)
    class Options:
        gain: float = 1.0
        offset: float = 0.0

    def __init__(self, gain, offset):
        self.gain, self.offset = gain, offset

    @classmethod
    def from_config(cls, config, options):
        return cls(options.gain, options.offset)

    def compute(self, inputs):
        return {"y": self.gain * inputs["x"] + self.offset}


class ByConstructor:
    """A user discipline built as cls(**options): its keyword parameters are the options."""

    name = "by_constructor"
    inputs = ("y",)
    outputs = ("f",)
    units = {"y": "1", "f": "1"}

    def __init__(self, power=2.0):
        self.power = power

    def compute(self, inputs):
        return {"f": np.abs(inputs["y"]) ** self.power}
'''


def _user_config(tmp_path: Path, declared: dict, by_constructor: dict) -> Path:
    (tmp_path / "user_keys.py").write_text(USER)
    raw = {"name": "user_keys",
           "disciplines": [{"name": "declared", "class": "user_keys:Declared", "options": declared},
                           {"name": "by_constructor", "class": "user_keys:ByConstructor", "options": by_constructor}],
           "problem": {"objective": "f", "design_variables": {"x": {"lower": -1, "upper": 1, "initial": 0.5}}}}
    return _write(tmp_path, yaml.safe_dump(raw, sort_keys=False), "user.yaml")


def test_a_user_discipline_declares_its_options_and_gets_the_same_check(tmp_path, capsys):
    good = _user_config(tmp_path, {"gain": 2.0, "offset": 0.5}, {"power": 2.0})
    cfg = load_config(good)
    from bev_mdo.config import resolve_disciplines

    d = {x.name: x for x in resolve_disciplines(cfg)}
    assert (d["declared"].inner if hasattr(d["declared"], "inner") else d["declared"]).gain == 2.0
    for declared, by_constructor, path, near in (({"gian": 2.0}, {}, "disciplines[0] (declared).options.gian", "gain"),
                                                  ({}, {"powr": 3}, "disciplines[1] (by_constructor).options.powr",
                                                   "power")):
        bad = _user_config(tmp_path, declared, by_constructor)
        for argv in (("evaluate", bad, "--set", "x=0.1", "--transport", "inprocess"),
                     ("optimize", bad, "--transport", "inprocess"),
                     ("optimize", bad)):
            code, out, err = _cli(capsys, *argv)
            assert code == 2, (argv, err)
            assert out == "" and len(err.strip().splitlines()) == 1, err
            assert f"{bad}: {path}: unknown key; did you mean '{near}'?" in err


def test_every_shipped_config_still_loads():
    files = sorted([*REPO.glob("config/*.yaml"), *REPO.glob("examples/**/*.yaml")])
    assert len(files) >= 8
    for f in files:
        load_config(f)


def test_a_class_without_from_config_may_declare_options_too(tmp_path):
    """Options declared in a dataclass, the class built as cls(**options) with the defaults filled."""
    (tmp_path / "plain_opts.py").write_text(
        "from dataclasses import dataclass\n\n\nclass Plain:\n    name = 'plain'\n    inputs = ('x',)\n"
        "    outputs = ('f',)\n    units = {'x': '1', 'f': '1'}\n\n    @dataclass\n    class Options:\n        power: float = 2.0\n"
        "        shift: float = 0.0\n\n    def __init__(self, power, shift):\n        self.power, self.shift = power, shift\n\n"
        "    def compute(self, inputs):\n        return {'f': inputs['x'] ** self.power + self.shift}\n")
    raw = {"disciplines": [{"name": "plain", "class": "plain_opts:Plain", "options": {"shift": 1.5}}],
           "search_path": [str(tmp_path)],
           "problem": {"objective": "f", "design_variables": {"x": {"lower": 0, "upper": 1}}}}
    from bev_mdo.config import resolve_disciplines

    (disc,) = resolve_disciplines(load_config(raw))
    inner = getattr(disc, "inner", disc)
    assert (inner.power, inner.shift) == (2.0, 1.5)
    raw["disciplines"][0]["options"] = {"shfit": 1.5}
    with pytest.raises(ValueError, match=r"disciplines\[0\] \(plain\).options.shfit: unknown key; did you mean 'shift'"):
        load_config(raw)


@pytest.mark.parametrize("declared, by_constructor, path, value", [
    ({"gain": float("nan")}, {}, "disciplines[0] (declared).options.gain", "nan"),
    ({}, {"power": float("inf")}, "disciplines[1] (by_constructor).options.power", "inf"),
    ({"offset": [1.0, float("-inf")]}, {}, "disciplines[0] (declared).options.offset[1]", "-inf")])
def test_a_non_finite_number_in_a_user_disciplines_options_exits_2_at_load(tmp_path, capsys, declared,
                                                                           by_constructor, path, value):
    # it loaded, and every point then failed with "non-finite output" (exit 1)
    bad = _user_config(tmp_path, declared, by_constructor)
    code, out, err = _cli(capsys, "evaluate", bad, "--set", "x=0.1", "--transport", "inprocess")
    assert code == 2 and out == "", err
    assert err == f"bev-mdo evaluate: error: {bad}: {path}: {value} must be a finite number\n"


def test_the_readme_example_discipline_refuses_a_nan_option_at_load():
    raw = yaml.safe_load(NEDC.read_text())
    raw["disciplines"] = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost",
                          {"name": "top_speed", "class": "examples.top_speed:TopSpeed",
                           "options": {"motor_max_speed_rad_s": float("nan")}}]
    raw["search_path"] = [str(REPO)]
    with pytest.raises(ValueError) as err:
        load_config(raw)
    assert str(err.value) == "<config>: disciplines[6] (top_speed).options.motor_max_speed_rad_s: nan must be a finite number"


def test_the_readme_example_discipline_refuses_text_for_a_number_option_at_load(tmp_path, capsys):
    # it loaded, then the constructor failed: "cannot build TopSpeed: TypeError: '<=' not supported ..."
    raw = yaml.safe_load(NEDC.read_text())
    raw["disciplines"] = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost",
                          {"name": "top_speed", "class": "examples.top_speed:TopSpeed",
                           "options": {"motor_max_speed_rad_s": "1675 rad/s"}}]
    raw["search_path"] = [str(REPO)]
    bad = _write(tmp_path, yaml.safe_dump(raw, sort_keys=False))
    code, out, err = _cli(capsys, "evaluate", bad, "--transport", "inprocess")
    assert code == 2 and out == "", err
    assert err == (f"bev-mdo evaluate: error: {bad}: disciplines[6] (top_speed).options.motor_max_speed_rad_s: "
                   "'1675 rad/s' must be a number (float)\n")
    raw["disciplines"][6]["options"] = {"motor_max_speed_rad_s": 1675}  # an int is a float's value
    from bev_mdo.config import RunConfig

    assert RunConfig.load(raw).disciplines[6].name == "top_speed"


class Typed:
    """Options annotated as strings (this module has ``from __future__ import annotations``)."""

    @dataclass(frozen=True)
    class Options:
        rate: float = 1.0
        count: int = 1
        on: bool = False
        label: str = "a"
        cap: float | None = None       # Optional: None or a float
        table: dict | None = None      # any other annotation: left alone


@pytest.mark.parametrize("key, value, what", [
    ("rate", "fast", "a number (float)"), ("rate", True, "a number (float)"),
    ("count", 2.5, "a whole number (int)"), ("count", False, "a whole number (int)"),
    ("on", 1, "true or false (bool)"), ("on", "yes", "true or false (bool)"),
    ("label", 3, "text (str)"), ("cap", "anything", "a number (float)")])
def test_an_option_of_the_wrong_type_is_refused_naming_its_key_and_type(key, value, what):
    from bev_mdo.mdo.user_class import read_options

    with pytest.raises(ValueError) as err:
        read_options(Typed, {key: value}, "disciplines[0] (typed).options")
    assert str(err.value) == f"disciplines[0] (typed).options.{key}: {value!r} must be {what}"


def test_options_of_the_declared_types_and_unchecked_annotations_are_taken():
    from bev_mdo.mdo.user_class import read_options

    given = {"rate": 2, "count": 3, "on": True, "label": "b", "cap": None, "table": [1]}
    assert read_options(Typed, given, "w") == Typed.Options(**given)
    assert read_options(Typed, {**given, "cap": 2}, "w").cap == 2


def test_text_for_a_constructor_option_with_a_number_default_exits_2_at_load_naming_it(tmp_path, capsys):
    # power=2.0 given '2 %' loaded, then every point failed with "TypeError: unsupported operand type(s) for ** ..."
    bad = _user_config(tmp_path, {}, {"power": "2 %"})
    code, out, err = _cli(capsys, "evaluate", bad, "--set", "x=0.1", "--transport", "inprocess")
    assert code == 2 and out == "", err
    assert err == (f"bev-mdo evaluate: error: {bad}: disciplines[1] (by_constructor).options.power: '2 %' must be "
                   "a number, as its default is\n")


class Built:
    """Options by constructor: checked by annotation, else (a number default) text and bools refused."""

    def __init__(self, loss=0.02, count: int = 1, table=None, mode="fast", cap: float | None = None):
        self.loss = loss


@pytest.mark.parametrize("key, value, what", [
    ("loss", "2 %", "a number, as its default is"), ("loss", True, "a number, as its default is"),
    ("count", 2.5, "a whole number (int)"), ("cap", "high", "a number (float)")])
def test_a_constructor_option_of_the_wrong_type_is_refused_naming_it(key, value, what):
    from bev_mdo.mdo.user_class import read_options

    with pytest.raises(ValueError) as err:
        read_options(Built, {key: value}, "w")
    assert str(err.value) == f"w.{key}: {value!r} must be {what}"
    given = {"loss": [0.01, 0.02], "count": 3, "table": "any", "mode": 5, "cap": None}  # what the class may take
    assert read_options(Built, given, "w") == given


def test_a_search_path_folder_that_does_not_exist_is_a_note_or_named_in_the_import_error(tmp_path, capsys):
    """It was said nowhere; a class not found named the folder among those looked in, as if it were there."""
    good = _user_config(tmp_path, {}, {})
    raw = yaml.safe_load(good.read_text())
    raw["search_path"] = ["no_such_folder"]
    cfg = _write(tmp_path, yaml.safe_dump(raw, sort_keys=False), "sp.yaml")
    code, out, err = _cli(capsys, "evaluate", cfg, "--set", "x=0.1", "--transport", "inprocess")
    assert code == 0 and err == f"bev-mdo evaluate: note: search_path: {tmp_path / 'no_such_folder'} does not exist\n"
    raw["disciplines"][0]["class"] = "elsewhere:Declared"
    cfg = _write(tmp_path, yaml.safe_dump(raw, sort_keys=False), "sp.yaml")
    code, out, err = _cli(capsys, "evaluate", cfg, "--set", "x=0.1", "--transport", "inprocess")
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert f"; search_path folder {tmp_path / 'no_such_folder'} does not exist)" in err


@pytest.mark.parametrize("drop, named", [
    ("road_load", "drag_area_m2 0.6412 m^2, rolling_resistance 0.007"),
    ("glider_kg", "glider_kg 1269.64 kg"),
    ("vehicle", "glider_kg 1269.64 kg, wheel_radius_m 0.316 m, drag_area_m2 0.6412 m^2, rolling_resistance 0.007")])
def test_a_car_left_to_the_leafs_mass_wheel_or_road_load_is_said(tmp_path, capsys, drop, named):
    """A Kona trial: a config without `road_load` ran on the Leaf's drag (117 Wh/km, not 134), without
    `glider_kg` on the Leaf's 1269.64 kg, without a vehicle section as a Leaf, with exit 0 and no word."""
    raw = yaml.safe_load((REPO / "config" / "leaf_epa_combined.yaml").read_text(encoding="utf-8"))
    if drop == "vehicle":
        del raw["vehicle"]
    else:
        del raw["vehicle"][drop]
    cfg = _write(tmp_path, yaml.safe_dump(raw, sort_keys=False))
    code, out, err = _cli(capsys, "evaluate", cfg, "--transport", "inprocess", "--no-record")
    assert code == 0
    assert (f"bev-mdo evaluate: note: vehicle: {named}: not in the config: the thesis' Nissan Leaf's values, where a run does not set them"
            in err.splitlines()), err
    code, out, err = _cli(capsys, "evaluate", REPO / "config" / "leaf_epa_combined.yaml", "--transport", "inprocess",
                          "--no-record")
    assert code == 0 and "Leaf's values" not in err  # a config that states them: no note


@pytest.mark.parametrize("road_load, named", [
    ({"a_n": 37.17, "b_n_per_m_s": 0.047, "c_n_per_m2_s2": 0.0144}, "c_n_per_m2_s2 0.0144 is outside"),
    ({"a_n": 37.17, "b_n_per_m_s": 0.047, "c_n_per_m2_s2": 0.0144, "mass_kg": 4250}, "a_n / (mass_kg g) 0.000892"),
    ({"a_n": 140.0, "b_n_per_m_s": 1.5, "c_n_per_m2_s2": 0.31, "mass_kg": 4250}, "a_n / (mass_kg g) 0.00336")])
def test_a_road_load_in_another_unit_is_said(tmp_path, capsys, road_load, named):
    """An EPA-data trial: a Model 3's coast-down pasted as EPA publishes it (lbf, lbf/mph, lbf/mph^2; test mass
    in lb) ran as a car using a third of its energy (41 Wh/km, 1709 km), every constraint ok and no word."""
    raw = yaml.safe_load((REPO / "config" / "leaf_epa_combined.yaml").read_text(encoding="utf-8"))
    raw["vehicle"]["road_load"] = road_load
    cfg = _write(tmp_path, yaml.safe_dump(raw, sort_keys=False))
    code, out, err = _cli(capsys, "evaluate", cfg, "--transport", "inprocess", "--no-record")
    assert code == 0  # a note, not a refusal: an unusual vehicle may be meant
    said = [line for line in err.splitlines() if line.startswith("bev-mdo evaluate: note: vehicle.road_load: ")]
    assert len(said) == 1 and named in said[0] and said[0].endswith("a unit mix-up? (read as given)"), err
    code, out, err = _cli(capsys, "evaluate", REPO / "config" / "leaf_epa_combined.yaml", "--transport", "inprocess",
                          "--no-record")
    assert code == 0 and "vehicle.road_load" not in err  # the Leaf's own coast-down: no note
    raw["vehicle"]["road_load"] = {"a_n": 99.6, "b_n_per_m_s": 0.0, "c_n_per_m2_s2": 0.3, "mass_kg": 2288.0}
    cfg = _write(tmp_path, yaml.safe_dump(raw, sort_keys=False))  # a review: the Ioniq 5's 0.00444, a real car
    code, out, err = _cli(capsys, "evaluate", cfg, "--transport", "inprocess", "--no-record")
    assert code == 0 and "vehicle.road_load" not in err, err


@pytest.mark.parametrize("cycle", ["cycle:\n", "cycle: {}\n", "cycle: {dt_s: 1.0}\n"])
def test_a_cycle_section_without_a_name_runs_the_nedc_and_says_so(tmp_path, capsys, cycle):
    """A malformed-files trial: `cycle:` left empty ran the NEDC with no word, and `cycle: {}` was refused
    ("cycle name must be a cycle name or CSV path, got None")."""
    text = (REPO / "config" / "leaf_nedc.yaml").read_text(encoding="utf-8")
    start = text.index("\ncycle:") + 1
    cfg = _write(tmp_path, text[:start] + cycle + text[text.index("\n", start) + 1:])
    code, out, err = _cli(capsys, "evaluate", cfg, "--transport", "inprocess", "--no-record")
    assert code == 0 and out.startswith("cycle: nedc 1180 s")
    assert "bev-mdo evaluate: note: cycle.name: not in the config: the NEDC, the thesis' cycle" in err.splitlines()
    code, out, err = _cli(capsys, "evaluate", REPO / "config" / "leaf_nedc.yaml", "--transport", "inprocess",
                          "--no-record")
    assert code == 0 and "cycle.name" not in err
    raw = yaml.safe_load(text)  # a review: no cycle and no vehicle section at all ran the NEDC with no word
    del raw["cycle"], raw["vehicle"]
    code, out, err = _cli(capsys, "evaluate", _write(tmp_path, yaml.safe_dump(raw), "bare.yaml"), "--transport",
                          "inprocess", "--no-record")
    assert code == 0 and "bev-mdo evaluate: note: cycle.name: not in the config: the NEDC" in err, err


def test_an_enormous_value_in_an_error_is_shortened_to_its_ends(tmp_path, capsys):
    """A malformed-files trial: a 900,000-item list where a number goes was echoed whole, a 4.5 MB error line."""
    text = (REPO / "config" / "leaf_nedc.yaml").read_text(encoding="utf-8")
    cfg = _write(tmp_path, text.replace("drag_area_m2: 0.6412", "drag_area_m2: [" + ", ".join(["0.6"] * 200_000) + "]"))
    code, out, err = _cli(capsys, "evaluate", cfg, "--transport", "inprocess", "--no-record")
    assert code == 2 and err.count("\n") == 1 and len(err) < 1200, len(err)
    assert "drag_area_m2 must be a number in [0.05, 3] m^2, got [0.6, 0.6" in err
    assert "characters left out) ... " in err and err.endswith("0.6, 0.6]\n")


def test_a_problem_whose_disciplines_read_no_cycle_gets_no_cycle_note(tmp_path, capsys):
    """The note of a config without a cycle name is for the disciplines that read it (energy, motor_speed)."""
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text(encoding="utf-8"))
    del raw["cycle"]
    raw["disciplines"] = ["vehicle_mass", "acceleration", "cost"]
    raw["problem"]["objective"], raw["problem"]["constraints"] = "powertrain_cost_usd", {"accel_time_0_100_s": {"upper": 10}}
    cfg = _write(tmp_path, yaml.safe_dump(raw, sort_keys=False))
    code, out, err = _cli(capsys, "evaluate", cfg, "--transport", "inprocess", "--no-record")
    assert code == 0 and "cycle.name" not in err, err


def test_two_projects_with_a_module_of_the_same_name_each_get_their_own_class(tmp_path, monkeypatch):
    """An API trial: two projects, each with its own disc.py defining Extra, studied in one session: the second
    config got the first one's class (the module Python had loaded), its outputs and numbers."""
    from bev_mdo.mdo import user_class

    monkeypatch.setattr(sys, "path", list(sys.path))
    monkeypatch.setattr(user_class, "_OURS", set())
    for name in ("a", "b"):
        (tmp_path / name).mkdir()
        (tmp_path / name / "disc_same_name.py").write_text(f"class Extra:\n    output = 'extra_{name}'\n")
    try:
        first = user_class.load_class("disc_same_name:Extra", [str(tmp_path / "a")])
        second = user_class.load_class("disc_same_name:Extra", [str(tmp_path / "b")])
        again = user_class.load_class("disc_same_name:Extra", [str(tmp_path / "b")])
    finally:
        sys.modules.pop("disc_same_name", None)
    assert (first.output, second.output) == ("extra_a", "extra_b") and again is second
    # a module load_class did not import is never dropped (the review: in a REPL started in the repository, a
    # config's class found in the working directory put it on sys.path, and a copy of bev_mdo on a later config's
    # search path dropped every bev_mdo module, loaded again from the copy)
    sys.path[:] = [p for p in sys.path if p not in ("", ".", str(REPO))]
    user_class.load_class("examples.sellar_vector:SellarDis1", [str(REPO)])
    (tmp_path / "c" / "bev_mdo" / "mdo").mkdir(parents=True)
    (tmp_path / "c" / "bev_mdo" / "__init__.py").write_text("")
    (tmp_path / "c" / "bev_mdo" / "mdo" / "discipline.py").write_text("class Discipline:\n    pass\n")
    from bev_mdo.mdo.discipline import Discipline

    assert user_class.load_class("bev_mdo.mdo.discipline:Discipline", [str(tmp_path / "c")]) is Discipline
