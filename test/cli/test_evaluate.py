import json
from pathlib import Path

import pytest

from bev_mdo.cli import main
from bev_mdo.cli.flags import parse_assignments

ROOT = Path(__file__).resolve().parents[2]
LEAF = ROOT / "config" / "leaf_nedc.yaml"


def run(capsys, *argv):
    """``bev-mdo evaluate ARGV``, in process unless ARGV chooses ROS (--transport, --attach)."""
    argv = [*map(str, argv)]
    if not {"--transport", "--attach"} & set(argv):
        argv += ["--transport", "inprocess"]
    code = main(["evaluate", *argv])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_json_schema_of_the_nominal_leaf(capsys):
    code, out, _ = run(capsys, LEAF, "--set", "motor_kw=80,gear_ratio=8", "battery_kwh=24", "--json")
    assert code == 0
    doc = json.loads(out)
    assert doc["design"] == {"motor_kw": 80.0, "gear_ratio": 8.0, "battery_kwh": 24.0}
    assert set(doc["outputs"]) >= {"vehicle_mass_kg", "energy_wh_per_km", "range_km", "accel_time_0_100_s",
                                   "motor_speed_max_rad_s", "powertrain_cost_usd"}
    assert doc["objective"] == {"name": "energy_wh_per_km", "value": doc["outputs"]["energy_wh_per_km"]}
    assert set(doc["constraints"]) == {"range_km", "motor_speed_max_rad_s", "accel_time_0_100_s"}
    for c in doc["constraints"].values():
        assert set(c) == {"value", "lower", "upper", "margin", "satisfied"}
    r = doc["constraints"]["range_km"]
    assert r["margin"] == pytest.approx(r["value"] - 170.0) and r["satisfied"] is (r["margin"] >= 0)
    assert doc["feasible"] is all(c["satisfied"] for c in doc["constraints"].values())


def test_table_shows_outputs_margins_and_feasibility(capsys):
    code, out, _ = run(capsys, LEAF, "--set", "gear_ratio=11")
    assert code == 0
    assert "motor_speed_max_rad_s" in out and "margin" in out and "feasible: NO" in out


def test_every_value_says_its_unit_in_the_table_and_the_json(capsys):
    """A Kona trial: evaluate printed energies, masses and speeds with no unit, in the table or the JSON, while
    compare and report.md had a unit column."""
    code, out, _ = run(capsys, LEAF, "--set", "motor_kw=80,gear_ratio=8,battery_kwh=24,load_kg=150")
    rows = {line.split("│")[1].strip(): [c.strip() for c in line.split("│")[2:-1]] for line in out.splitlines()
            if line.startswith("│")}
    assert code == 0 and rows["motor_kw"] == ["80", "kW", "design"] and rows["load_kg"] == ["150", "kg", "parameter"]
    assert rows["energy_wh_per_km"][1:] == ["Wh/km", "objective (min), from the battery"] and rows["gear_ratio"][1] == "–"
    assert rows["range_km"][-2:] == ["km", "yes"] and rows["accel_time_0_100_s"][-2] == "s"  # the constraints' rows
    code, out, _ = run(capsys, LEAF, "--set", "motor_kw=80,gear_ratio=8,battery_kwh=24,load_kg=150", "--json")
    units = json.loads(out)["units"]
    assert units["energy_wh_per_km"] == "Wh/km" and units["load_kg"] == "kg" and units["vehicle_mass_kg"] == "kg"


def test_the_objective_line_and_the_ssbj_range_say_their_units(capsys):
    """The last line gave the objective with no unit, and the SSBJ example declared its range (nmi) and weights
    (lb) as dimensionless."""
    code, out, _ = run(capsys, LEAF)
    assert code == 0 and out.rstrip().splitlines()[-1].startswith("objective energy_wh_per_km = 100.") \
        and " Wh/km; feasible" in out
    code, out, _ = run(capsys, ROOT / "examples" / "ssbj" / "ssbj_mdf.yaml", "--json")
    units = json.loads(out)["units"]
    assert (units["y_4"], units["y_14[1]"], units["y_23"], units["y_34"]) == ("nmi", "lb", "lb", "1/h")
    assert units["x_shared[1]"] == "1"  # t/c, ft, Mach, AR, deg and ft^2: one unit a variable
    code, out, _ = run(capsys, ROOT / "examples" / "ssbj" / "ssbj_mdf.yaml")
    assert out.rstrip().splitlines()[-1].startswith("objective y_4 = ") and " nmi; feasible" in out


def test_parameter_override_changes_energy(capsys):
    _, base, _ = run(capsys, LEAF, "--json")
    _, more, _ = run(capsys, LEAF, "--set", "drag_area_m2=0.8", "--json")
    assert json.loads(more)["outputs"]["energy_wh_per_km"] > json.loads(base)["outputs"]["energy_wh_per_km"]


@pytest.mark.parametrize("argv,msg", [
    (["--set", "motor_kw"], "--set 'motor_kw' must be NAME=VALUE"),
    (["--set", "motor_kw=fast"], "value must be a number"),
    # a list for a two-speed gearbox: "'[9.04': value must be a number" and "'4.7' must be NAME=VALUE"
    (["--set", "gear_ratio=[9.04,4.7]"], "--set gear_ratio=[9.04,4.7]: --set takes one number per name (NAME=VALUE) "
                                         "(a two-speed gearbox is gear_count=2 with gear_ratio_2 for its second "
                                         "gear: --set gear_count=2,gear_ratio=9.04,gear_ratio_2=4.7)"),
    (["--set", "gear_ratio=9.04,4.7"], "--set gear_ratio=9.04,4.7: --set takes one number per name (NAME=VALUE) (a "
                                       "two-speed gearbox is gear_count=2 with gear_ratio_2"),
    (["--set", "motor_kw=80,90"], "--set motor_kw=80,90: --set takes one number per name (NAME=VALUE)\n"),
    (["--set", "warp=1"], "unknown design names ['warp']"),
    # a value that is not finite was evaluated "as given" (a note that it is outside its bounds, exit 1)
    (["--set", "motor_kw=nan"], "--set motor_kw=nan: a design value must be a finite number"),
    (["--set", "motor_kw=inf"], "--set motor_kw=inf: a design value must be a finite number"),
    (["--set", "motor_kw=1e400"], "--set motor_kw=1e400: a design value must be a finite number"),  # it said inf
    # float() reads 1_00 as 100
    (["--set", "motor_kw=1_00"], "--set motor_kw=1_00: an underscore in a number is taken for a typo; write the "
                                 "number without it"),
    (["--set", "drag_area_m2=-inf"], "--set drag_area_m2=-inf: a design value must be a finite number"),
    # a value no model can evaluate (outside a physical design limit or a parameter's range) printed a
    # table of NaN and exited 1, "evaluation failed"
    (["--set", "motor_kw=-5"], "motor_kw: -5 is outside [1, 1000] kW, where discipline 'vehicle_mass' accepts "
                               "it; such a design cannot be evaluated"),
    (["--set", "gear_ratio=60"], "gear_ratio: 60 is outside [0.5, 50], where discipline"),
    (["--set", "glider_kg=-100"], "glider_kg: -100 is outside [200, 5000] kg, where discipline 'vehicle_mass'"),
    # the last one used to win silently
    (["--set", "motor_kw=70,motor_kw=80"], "--set motor_kw: given twice (70 and 80)"),
    (["--set", "motor_kw=70", "gear_ratio=8", "motor_kw=80"], "--set motor_kw: given twice (70 and 80)"),
    # an empty item was skipped without a word; a bare nan after a value was "'nan' must be NAME=VALUE"
    (["--set", "motor_kw=100,,battery_kwh=25"], "--set 'motor_kw=100,,battery_kwh=25': an empty item between commas"),
    (["--set", ",motor_kw=100"], "--set ',motor_kw=100': an empty item between commas"),
    (["--set", "motor_kw=100,nan"], "--set motor_kw=100,nan: --set takes one number per name (NAME=VALUE)\n"),
    (["--set", "motor_kw=100,-inf"], "--set motor_kw=100,-inf: --set takes one number per name (NAME=VALUE)\n"),
    # a malformed-files trial: "an underscore in a number is taken for a typo"
    (["--set", "motor_kw=80;gear_ratio=8"], "--set 'motor_kw=80;gear_ratio=8': two NAME=VALUE in one item; separate"),
    # an AWD trial: "did you mean 'motor_kg_per_kw'?" and 50 names, where the config's own says this
    (["--set", "motor_rear_kw=165"], "design variable 'motor_rear_kw' does not exist in topology SM-SA (single axle)"),
])
def test_bad_input_is_one_line_exit_2(capsys, argv, msg):
    code, _, err = run(capsys, LEAF, *argv)
    assert code == 2 and msg in err and err.count("\n") == 1


def test_json_of_a_failed_evaluation_is_strict_with_null(capsys, sellar_raising):
    """allow_nan=True wrote a failed evaluation's outputs as bare NaN, which is not JSON."""
    cfg = sellar_raising
    code, out, _ = run(capsys, cfg, "--json")

    def refuse(word):
        raise AssertionError(f"{word} in the --json output")
    doc = json.loads(out, parse_constant=refuse)
    assert code == 1 and doc["ok"] is False and "the solver diverged" in doc["error"]
    assert doc["outputs"]["w"] is None and doc["objective"]["value"] is None


def test_missing_config_exit_2(capsys, tmp_path):
    code, _, err = run(capsys, tmp_path / "nope.yaml")
    assert code == 2 and "no such config file" in err


@pytest.mark.parametrize("argv", [["evaluate"], ["optimize"], ["sweep"], ["graph"], ["node", "energy", "--config"]])
def test_a_directory_given_as_the_config_is_said_to_be_one(capsys, tmp_path, argv):
    # it was "no such config file", though the path exists
    code = main([*argv, str(tmp_path)])
    out = capsys.readouterr()
    assert code == 2 and out.out == ""
    assert out.err == (f"bev-mdo {argv[0]}: error: {tmp_path}: is a directory, not a config file; give the path of "
                       "a config YAML file\n")


@pytest.mark.parametrize("flags", [["--transport", "ros"], ["--attach"]])
def test_ros_without_rclpy_is_a_usage_error(capsys, monkeypatch, flags):
    import sys
    monkeypatch.setitem(sys.modules, "rclpy", None)  # as if rclpy were not installed
    code, _, err = run(capsys, LEAF, *flags)
    assert code == 2 and "--transport ros needs the ROS transport" in err and "--transport inprocess" in err


def test_a_broken_bev_mdo_module_is_not_reported_as_a_missing_transport(capsys, monkeypatch):
    import sys
    monkeypatch.setitem(sys.modules, "bev_mdo.ros.client", None)  # our own module fails to import
    code, _, err = run(capsys, LEAF, "--attach")  # an unexpected error: one line naming it, exit status 7
    assert code == 7 and "needs the ROS transport" not in err
    assert err.startswith("bev-mdo evaluate: error: ModuleNotFoundError: ") and "bev_mdo.ros.client" in err


def test_attach_with_no_nodes_running_names_the_missing_disciplines(capsys, tmp_path, ros_domain):
    import yaml

    cfg = yaml.safe_load(open(LEAF))
    cfg["ros"] = {"domain_id": ros_domain, "discovery_wait_s": 0.5}
    path = tmp_path / "leaf.yaml"
    path.write_text(yaml.safe_dump(cfg))
    code, _, err = run(capsys, path, "--attach")
    assert code == 6 and err.count("\n") == 1  # start-up gave up (documented exit 6), one line
    for name in ("vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost"):
        assert name in err


def test_parse_assignments_merges_commas_and_spaces():
    assert parse_assignments(["a=1,b=2", "c=-3e2", "d=4,"]) == {"a": 1.0, "b": 2.0, "c": -300.0, "d": 4.0}


def test_a_config_names_a_parameter_set_file_of_your_own(capsys, tmp_path):
    """The calibrated model with the user's own constants: the config names the file by its path."""
    import yaml

    from bev_mdo.models.params import load_parameter_set

    shipped = load_parameter_set("epa2022_quasi_static")
    own = tmp_path / "mine.yaml"
    own.write_text(yaml.safe_dump({"energy_model": "quasi_static", "parameters": {**shipped, "charger_efficiency": 0.7}}))
    text = (ROOT / "config" / "leaf_epa_combined.yaml").read_text()
    assert "parameter_set: epa2022_quasi_static" in text
    cfg = tmp_path / "mine_cfg.yaml"
    cfg.write_text(text.replace("parameter_set: epa2022_quasi_static", f"parameter_set: {own}"))
    design = ("--set", "motor_kw=80,gear_ratio=8,battery_kwh=24", "--json")
    code, out, err = run(capsys, cfg, *design)
    assert code == 0, err
    ref = json.loads(run(capsys, ROOT / "config" / "leaf_epa_combined.yaml", *design)[1])
    mine = json.loads(out)
    # only the charger differs from the shipped set's (0.81): wall energy scales with 1 / eta
    eta = shipped["charger_efficiency"]
    wall = "energy_wall_wh_per_km"
    assert mine["outputs"][wall] != pytest.approx(ref["outputs"][wall])
    assert mine["outputs"][wall] * 0.7 == pytest.approx(ref["outputs"][wall] * eta)
    # the energy from the battery (what range reads) does not depend on the charger
    assert mine["outputs"]["energy_wh_per_km"] == pytest.approx(ref["outputs"]["energy_wh_per_km"], rel=1e-12)
    assert mine["outputs"]["range_km"] == pytest.approx(ref["outputs"]["range_km"], rel=1e-12)


def test_an_override_the_road_load_replaces_is_refused(capsys):
    code, out, err = run(capsys, ROOT / "config" / "leaf_epa_combined.yaml", "--set",
                         "motor_kw=80,gear_ratio=8,battery_kwh=24,drag_area_m2=2")
    assert code == 2 and out == "" and err.count("\n") == 1 and "unknown design names ['drag_area_m2']" in err


def test_a_cycle_cut_at_speed_is_noted_on_stderr_once(capsys, tmp_path, monkeypatch):
    import yaml

    rows = (ROOT / "bev_mdo" / "data" / "drive_cycles" / "epa_hwfet.csv").read_text().splitlines()
    seg = [rows[0]] + [f"{float(t) - 100:g},{v}" for t, v in (r.split(",") for r in rows[1:]) if 100 <= float(t) <= 400]
    (tmp_path / "seg.csv").write_text("\n".join(seg) + "\n")
    raw = yaml.safe_load((ROOT / "config" / "leaf_nedc.yaml").read_text())
    raw["cycle"]["name"] = "seg.csv"
    (tmp_path / "seg.yaml").write_text(yaml.safe_dump(raw))
    monkeypatch.chdir(tmp_path)
    code, out, err = run(capsys, "seg.yaml", "--json")
    assert code == 0 and json.loads(out)["objective"]["value"] > 0
    notes = [line for line in err.splitlines() if "note:" in line]
    assert len(notes) == 1 and notes[0].startswith(  # the file by where it was read: beside the config
        f"bev-mdo evaluate: note: {(tmp_path / 'seg.csv').resolve()} starts at 78 km/h and ends at 92")
    code, _, err = run(capsys, "seg.yaml")  # a second command in the same process notes it again
    assert code == 0 and sum("note:" in line for line in err.splitlines()) == 1


def test_table_names_a_maximised_objective_as_max(capsys):
    """SSBJ maximises its range (objective: {name: y_4, maximize: true}): the table said 'objective (min)'."""
    code, out, _ = run(capsys, ROOT / "examples" / "ssbj" / "ssbj_mdf.yaml")
    assert code == 0
    row = next(line for line in out.splitlines() if "y_4" in line)
    assert "objective (max)" in row and "(min)" not in out
    code, out, _ = run(capsys, LEAF)
    assert "objective (min)" in next(line for line in out.splitlines() if "energy_wh_per_km" in line)


def test_a_design_outside_the_bounds_is_evaluated_with_a_note_and_is_infeasible(capsys):
    """It was reported 'feasible: yes' (JSON true) while optimize's answers call a point outside its bounds
    infeasible whatever its constraints say (docs/answers.md) and compare refuses it."""
    code, out, err = run(capsys, LEAF, "--set", "motor_kw=200,gear_ratio=8", "--json")
    report = json.loads(out)
    assert code == 0 and report["design"]["motor_kw"] == 200
    assert err.strip() == "bev-mdo evaluate: note: motor_kw = 200 is outside its bounds [40, 120] (evaluated as given)"
    assert report["feasible"] is False and all(c["satisfied"] for c in report["constraints"].values())
    assert report["notes"][0] == ("motor_kw = 200 is outside its bounds [40, 120]: infeasible whatever the "
                                  "constraints say (evaluated as given)")
    code, out, err = run(capsys, LEAF, "--set", "motor_kw=200,gear_ratio=8")
    assert out.rstrip().endswith("feasible: NO")
    code, out, err = run(capsys, LEAF, "--set", "motor_kw=120,gear_ratio=8", "--json")
    assert code == 0 and "note:" not in err and json.loads(out)["feasible"] is True  # on the bound is inside


def test_evaluate_says_when_the_packs_power_limits_the_0_100_time(capsys):
    """The 0-100 km/h time within the pack's 5C power (x 0.9 to the shaft) gave no sign of it: 20 kWh give
    80.3 kW at the shaft, below a 120 kW motor; 24 kWh (96.3 kW) do not limit an 80 kW one."""
    code, out, _ = run(capsys, LEAF, "--set", "motor_kw=120,battery_kwh=20", "--json")
    lim = json.loads(out)["accel_battery_limit"]
    assert code == 0 and lim["limits"] is True and lim["motors_rated_power_kw"] == 120.0
    assert lim["pack_shaft_power_kw"] == pytest.approx(80.266, abs=1e-2)
    code, out, _ = run(capsys, LEAF, "--set", "motor_kw=120,battery_kwh=20")
    assert ("note: the pack limits the 0-100 km/h time: 80.3 kW at the shaft, below the motors' rated 120.0 kW "
            "(9.16 s; 6.58 s without the pack's limit)") in " ".join(out.split()), out  # (the note may wrap)
    code, out, _ = run(capsys, LEAF, "--set", "motor_kw=80,battery_kwh=24", "--json")
    assert json.loads(out)["accel_battery_limit"]["limits"] is False and "notes" not in json.loads(out)
    # a short gear: below 100 km/h the motor stays under its base speed and uses about 69 of its 90 kW, so the
    # pack's 80.3 kW bind nothing (the note said the pack limited the time, which was the same without the limit)
    code, out, _ = run(capsys, LEAF, "--set", "motor_kw=90,gear_ratio=2.5,battery_kwh=20", "--json")
    doc = json.loads(out)
    assert doc["accel_battery_limit"]["limits"] is False and "pack limits" not in " ".join(doc.get("notes", []))
    assert doc["accel_battery_limit"]["time_without_limit_s"] == doc["outputs"]["accel_time_0_100_s"]
    code, out, _ = run(capsys, LEAF, "--set", "motor_kw=120,battery_kwh=20,battery_to_shaft_efficiency=0", "--json")
    assert "accel_battery_limit" not in json.loads(out) and "notes" not in json.loads(out)  # no limit (thesis set)


def test_a_design_past_the_vehicle_mass_limit_keeps_the_outputs_that_do_not_depend_on_mass(capsys):
    """A 2600 kWh battery makes 21.7 t, past the models' 20 000 kg: every output was NaN, the motor speed and
    the cost too (they do not depend on mass), and the error line named point 0 and its inputs and wrapped."""
    _, good, _ = run(capsys, LEAF, "--set", "motor_kw=80,gear_ratio=8,battery_kwh=24", "--json")
    code, out, err = run(capsys, LEAF, "--set", "motor_kw=80,gear_ratio=8,battery_kwh=2600", "--json")
    doc, good = json.loads(out), json.loads(good)
    assert code == 1 and not doc["ok"]
    why = "energy: ValueError: vehicle_mass_kg must be in [100, 20000] kg, got 21682.8"
    assert doc["error"] == why
    outs = doc["outputs"]
    assert outs["motor_speed_max_rad_s"] == pytest.approx(good["outputs"]["motor_speed_max_rad_s"], rel=1e-12)
    assert outs["vehicle_mass_kg"] == pytest.approx(21682.8, abs=0.1) and outs["powertrain_cost_usd"] > 0
    assert outs["energy_wh_per_km"] is None and outs["range_km"] is None  # they depend on the mass
    assert doc["constraints"]["motor_speed_max_rad_s"]["satisfied"]
    code, out, _ = run(capsys, LEAF, "--set", "motor_kw=80,gear_ratio=8,battery_kwh=2600")
    assert code == 1 and f"evaluation failed: {why}\n" in out


def test_a_set_parameter_is_shown_as_a_parameter_not_a_design_variable(capsys):
    code, out, _ = run(capsys, LEAF, "--set", "load_kg=130", "--json")
    doc = json.loads(out)
    assert code == 0 and doc["design"] == {"motor_kw": 80.0, "gear_ratio": 8.0, "battery_kwh": 24.0}
    assert doc["parameters"] == {"load_kg": 130.0}
    code, out, _ = run(capsys, LEAF, "--set", "load_kg=130")
    row = next(line for line in out.splitlines() if "load_kg" in line)
    assert "parameter" in row and "design" not in row, row



def test_the_table_says_the_cycles_duration_distance_and_top_speed(capsys, tmp_path):
    """A cycle in m/s under the km/h header (a 50 km/h cruise written 13.89) was evaluated with nothing of the
    cycle shown: its 13.9 km/h top speed is now the first line."""
    t = range(0, 601, 10)
    (tmp_path / "cruise.csv").write_text("time_s,speed_kmh\n" + "".join(
        f"{s},{0 if s in (0, 600) else 13.89}\n" for s in t))
    cfg = tmp_path / "c.yaml"
    cfg.write_text(LEAF.read_text().replace("cycle: {name: nedc", "cycle: {name: cruise.csv"))
    code, out, _ = run(capsys, cfg)
    assert code in (0, 1) and out.splitlines()[0] == "cycle: cruise 600 s, 2.28 km, top 13.9 km/h"
    code, out, _ = run(capsys, ROOT / "config" / "leaf_epa_combined.yaml")
    # and what each is for (an EPA-data trial: US06 read as if the energy were on it)
    assert out.splitlines()[0] == ("cycles: epa_us06 600 s, 12.89 km, top 129.2 km/h (cycle.name: not the energy "
                                   "discipline's); epa_udds 1369 s, 11.99 km, top 91.3 km/h (energy: 0.55 of the "
                                   "distance); epa_hwfet 765 s, 16.51 km, top 96.4 km/h (energy: 0.45 of the distance)")
    rows = {r.split("│")[1].strip(): r.split("│")[4].strip() for r in out.splitlines() if r.count("│") == 5}
    assert rows["range_km"] == "output, unadjusted: an EPA label's ~0.7x"  # a window sticker's range is not this
    assert rows["energy_wall_wh_per_km"] == "objective (min), from the wall"
    code, out, _ = run(capsys, LEAF)  # a review: on the NEDC no EPA label is meant
    rows = {r.split("│")[1].strip(): r.split("│")[4].strip() for r in out.splitlines() if r.count("│") == 5}
    assert rows["range_km"] == "output, unadjusted"
    code, out, _ = run(capsys, LEAF, "--json")
    assert json.loads(out)["design"]  # JSON as it was


def test_a_name_near_a_design_variable_gets_it_as_the_nearest(capsys):
    """An EPA-data trial: `--set gear=9.03` listed some 50 names with no nearest one (`gear` is 0.57 like
    `gear_ratio` by difflib, below the 0.6 its parameters need)."""
    code, _, err = run(capsys, LEAF, "--set", "gear=9.03")
    assert code == 2 and len(err.strip().splitlines()) == 1 and "did you mean 'gear_ratio'?" in err, err
