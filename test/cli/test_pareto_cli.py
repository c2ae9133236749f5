"""Topology as one config setting (``vehicle.topology``) and bad topology input, through the CLI:
``bev-mdo pareto`` and ``bev-mdo optimize --transport inprocess`` exit 2 with one clear line."""
import copy
import csv
import json
from pathlib import Path

import pytest
import yaml

from bev_mdo.cli import main
from bev_mdo.studies.topologies import TOPOLOGY_BOUNDS, config_for_topology, config_topology

ARTEMIS = Path(__file__).resolve().parents[2] / "config" / "topologies_artemis.yaml"
DVS = {"SM-SA": ("motor_kw", "gear_ratio", "battery_kwh"), "IWM-SA": ("motor_kw", "battery_kwh"),
       "DM-DA": ("motor_kw", "gear_ratio", "motor_rear_kw", "gear_ratio_rear", "battery_kwh"),
       "IWM-DA": ("motor_kw", "motor_rear_kw", "battery_kwh")}


def _raw(topology="SM-SA", dvs=None):
    raw = yaml.safe_load(ARTEMIS.read_text())
    raw["cycle"] = {"name": "nedc", "dt_s": 2.0}  # fast
    raw["vehicle"]["topology"] = topology
    if dvs is not None:
        raw["problem"]["design_variables"] = {k: {"lower": 10, "upper": 90, "initial": 40} for k in dvs}
    return raw


def _write(tmp_path, raw, name="cfg.yaml"):
    p = tmp_path / name
    p.write_text(yaml.safe_dump(raw))
    return p


def _run(capsys, *argv):
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err
    return code, err


def _commands(cfg, tmp_path):
    return (("pareto", cfg, "--out", tmp_path / "o", "--generations", "1", "--pop", "4", "--transport", "inprocess"),
            ("optimize", cfg, "--transport", "inprocess"))


def test_the_shipped_config_sets_topology_once():
    raw = yaml.safe_load(ARTEMIS.read_text())
    assert raw["vehicle"]["topology"] == "SM-SA" and config_topology(raw) == "SM-SA"
    assert not any(isinstance(e, dict) and "topology" in (e.get("options") or {}) for e in raw["disciplines"])


def test_unknown_vehicle_topology_exit_2(tmp_path, capsys):
    cfg = _write(tmp_path, _raw("WHEEL-9"))
    for argv in _commands(cfg, tmp_path):
        code, err = _run(capsys, *argv)
        assert code == 2, argv
        assert len(err.strip().splitlines()) == 1, err
        assert f"bev-mdo {argv[0]}: error: {cfg}: vehicle: topology must be one of SM-SA, DM-DA, IWM-SA, IWM-DA, " \
               "got 'WHEEL-9'" in err


@pytest.mark.parametrize("flag", [("--all-topologies",), ("--topology", "DM-DA")])
def test_a_topology_study_of_a_bad_config_names_the_file(tmp_path, capsys, flag):
    """'error: <config>: problem.constraints.top_speed_kmh: no discipline produces it' with --all-topologies; the
    same config named its file everywhere else."""
    raw = _raw()
    raw["problem"]["constraints"]["top_speed_kmh"] = {"lower": 250}
    cfg = _write(tmp_path, raw)
    code, err = _run(capsys, "pareto", cfg, *flag, "--out", tmp_path / "o", "--generations", "1", "--pop", "4",
                     "--transport", "inprocess")
    assert code == 2 and err.count("\n") == 1
    assert f"bev-mdo pareto: error: {cfg}: problem.constraints.top_speed_kmh: no discipline produces it" in err


def test_unknown_topology_flag_exit_2(tmp_path, capsys):
    code, err = _run(capsys, "pareto", _write(tmp_path, _raw()), "--topology", "WHEEL-9", "--out", tmp_path / "o",
                     "--transport", "inprocess")
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "topology must be one of SM-SA, DM-DA, IWM-SA, IWM-DA, got 'WHEEL-9'" in err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("topo,extra", [("IWM-SA", "gear_ratio"), ("SM-SA", "motor_rear_kw"),
                                        ("IWM-DA", "gear_ratio_rear"), ("IWM-SA", "motor_rear_kw")])
def test_variable_the_topology_does_not_have_exit_2(tmp_path, capsys, topo, extra):
    cfg = _write(tmp_path, _raw(topo, DVS[topo] + (extra,)))
    for argv in _commands(cfg, tmp_path):
        code, err = _run(capsys, *argv)
        assert code == 2, argv
        assert len(err.strip().splitlines()) == 1, err
        assert f"design variable {extra!r} does not exist in topology {topo} (" in err
        assert "its design variables: " in err


def test_discipline_option_disagreeing_with_vehicle_topology_exit_2(tmp_path, capsys):
    raw = _raw("IWM-SA", DVS["IWM-SA"])
    raw["disciplines"][1]["options"]["topology"] = "DM-DA"  # energy
    cfg = _write(tmp_path, raw)
    for argv in _commands(cfg, tmp_path):
        code, err = _run(capsys, *argv)
        assert code == 2 and len(err.strip().splitlines()) == 1
        assert "disciplines disagree on the topology: ['DM-DA', 'IWM-SA']" in err


def test_config_topology_reads_vehicle_then_options():
    assert config_topology(_raw("iwm-da")) == "IWM-DA"
    legacy = _raw()
    del legacy["vehicle"]["topology"]
    assert config_topology(legacy) == "SM-SA"
    legacy["disciplines"] = [{"name": e, "options": {"topology": "DM-DA"}} if isinstance(e, str) else
                             {**e, "options": {**e["options"], "topology": "DM-DA"}} for e in legacy["disciplines"]]
    assert config_topology(legacy) == "DM-DA"


@pytest.mark.parametrize("legacy", [False, True])
def test_config_for_topology_rewrites_the_one_setting(legacy):
    from bev_mdo.config import load_config, resolve_disciplines

    raw = _raw()
    if legacy:  # per-discipline options, as before vehicle.topology existed: rewritten too
        del raw["vehicle"]["topology"]
        raw["disciplines"] = [{"name": e, "options": {"topology": "SM-SA"}} if isinstance(e, str) else
                              {**e, "options": {**e["options"], "topology": "sm-sa"}} for e in raw["disciplines"]]
    before = copy.deepcopy(raw)
    for t in ("DM-DA", "IWM-SA", "SM-SA"):
        cfg = config_for_topology(raw, t.lower())
        assert cfg["vehicle"]["topology"] == t and config_topology(cfg) == t
        for e in cfg["disciplines"]:
            if isinstance(e, dict) and "topology" in (e.get("options") or {}):
                assert legacy and e["options"]["topology"] == t
        dvs = cfg["problem"]["design_variables"]
        if t == "SM-SA":
            assert dvs == raw["problem"]["design_variables"]  # the config's own problem is kept
        else:
            assert set(dvs) == set(TOPOLOGY_BOUNDS[t]) | {"battery_kwh"}
            for k in set(dvs) & set(raw["problem"]["design_variables"]):  # the config's bounds are kept
                assert dvs[k] == raw["problem"]["design_variables"][k], (t, k)
        discs = {d.name: d for d in resolve_disciplines(load_config(cfg))}
        assert {discs[n].topology.name for n in ("vehicle_mass", "energy", "cycle_range", "acceleration",
                                                 "cost")} == {t}
    assert raw == before  # the input is not modified


def test_a_baseline_of_the_configs_own_topology_is_left_out_of_another_topologys_problem():
    """pareto --topology DM-DA on a config with an SM-SA baseline stopped: 'problem.baseline.design misses
    design variables ['motor_rear_kw', 'gear_ratio_rear']' (exit 2)."""
    from bev_mdo.config import load_config

    raw = _raw()
    raw["problem"]["baseline"] = {"name": "mine", "design": {"motor_kw": 80, "gear_ratio": 7.9, "battery_kwh": 24}}
    assert "baseline" not in config_for_topology(raw, "DM-DA")["problem"]
    load_config(config_for_topology(raw, "DM-DA"))
    assert config_for_topology(raw, "SM-SA")["problem"]["baseline"]["name"] == "mine"  # its own topology: kept


def test_a_geared_baseline_is_left_out_of_an_in_wheel_topologys_problem():
    """pareto --topology IWM-SA on a config with an SM-SA baseline stopped: 'problem.baseline.design.gear_ratio:
    neither a design variable nor a discipline parameter' (the baseline has every IWM-SA variable, and one more)."""
    from bev_mdo.config import load_config

    raw = _raw()
    raw["problem"]["baseline"] = {"name": "mine", "design": {"motor_kw": 80, "gear_ratio": 7.9, "battery_kwh": 24}}
    for topology in ("IWM-SA", "IWM-DA"):
        assert "baseline" not in config_for_topology(raw, topology)["problem"]
        load_config(config_for_topology(raw, topology))


def test_pareto_runs_the_vehicle_topology(tmp_path, capsys):
    """Without --topology: the config as written (its vehicle.topology), its three objectives, no study."""
    out = tmp_path / "o"
    code, err = _run(capsys, "pareto", _write(tmp_path, _raw("IWM-SA", DVS["IWM-SA"])), "--generations", "1",
                     "--pop", "4", "--no-plots", "--out", out, "--transport", "inprocess")
    assert code == 0, err
    doc = json.loads((out / "front.json").read_text())
    assert [o["name"] for o in doc["objectives"]] == ["energy_wh_per_km", "accel_time_0_100_s", "powertrain_cost_usd"]
    assert sorted(doc["design_variables"]) == sorted(DVS["IWM-SA"])
    rows = list(csv.DictReader((out / "front.csv").open()))
    assert rows and "gear_ratio" not in rows[0] and "motor_rear_kw" not in rows[0]
    assert not (out / "benchmark.csv").exists() and not (out / "summary.json").exists()
    assert "SM-SA" not in err and "IWM-SA" not in err  # no study, no topology label


def test_the_topology_study_labels_each_topology_and_keeps_the_users_bounds(tmp_path, capsys):
    raw = _raw("SM-SA")
    raw["problem"]["design_variables"]["motor_kw"] = {"lower": 50, "upper": 110, "initial": 80}
    out = tmp_path / "o"
    code, err = _run(capsys, "pareto", _write(tmp_path, raw), "--topology", "DM-DA", "--generations", "1",
                     "--pop", "4", "--no-plots", "--out", out, "--transport", "inprocess")
    assert code == 0, err
    assert "DM-DA: NSGA-II 4 x 1" in err and "SM-SA" not in err
    # each topology's motor power per motor and in total (an in-wheel motor_kw is per motor: like for like?)
    assert "motor power motor_kw [50, 110] kW, motor_rear_kw [20, 90] kW: 70-200 kW in total" in err
    timing = json.loads((out / "summary.json").read_text())["timing"]
    assert list(timing) == ["DM-DA"]
    dvs = timing["DM-DA"]["design_variables"]
    assert dvs["motor_kw"] == [50, 110] and dvs["gear_ratio"] == [4, 9.4] and dvs["battery_kwh"] == [18, 30]
    assert dvs["motor_rear_kw"] == list(TOPOLOGY_BOUNDS["DM-DA"]["motor_rear_kw"][:2])  # not in the config
    rows = list(csv.DictReader((out / "pareto_DM-DA.csv").open()))
    assert rows and all(50 <= float(r["motor_kw"]) <= 110 for r in rows)
    bench = next(csv.DictReader((out / "benchmark.csv").open()))
    assert bench["topology"] == "DM-DA"


def test_the_command_lines_bounds_go_to_each_studied_topology(tmp_path, capsys):
    """--bound was checked against the config as written (SM-SA): motor_rear_kw, a DM-DA variable, was
    refused as 'not a design variable', and gear_ratio with --topology IWM-SA was dropped with the
    variable, without a word."""
    cfg = _write(tmp_path, _raw("SM-SA"))
    study = ("--generations", "1", "--pop", "4", "--no-plots", "--transport", "inprocess")
    code, err = _run(capsys, "pareto", cfg, "--topology", "DM-DA", "--bound", "motor_rear_kw=30:40", "--out",
                     tmp_path / "dm", *study)
    assert code == 0, err
    assert json.loads((tmp_path / "dm" / "summary.json").read_text())["timing"]["DM-DA"]["design_variables"][
        "motor_rear_kw"] == [30, 40]
    code, err = _run(capsys, "pareto", cfg, "--topology", "IWM-SA", "--bound", "gear_ratio=5:6", "--out",
                     tmp_path / "iwm", *study)
    assert code == 2 and "(IWM-SA): --bound 'gear_ratio': not a design variable" in err
    code, err = _run(capsys, "pareto", cfg, "--all-topologies", "--bound", "gear_ratio=5:6", "--out", tmp_path / "all",
                     *study)
    assert code == 0, err
    timing = json.loads((tmp_path / "all" / "summary.json").read_text())["timing"]
    assert [timing[t]["design_variables"].get("gear_ratio") for t in ("SM-SA", "DM-DA", "IWM-SA", "IWM-DA")] == [
        [5, 6], [5, 6], None, None]
    assert "IWM-DA: NSGA-II 4 x 1 over inprocess; motor power motor_kw [40, 130] kW x 2 motors, motor_rear_kw " \
           "[10, 70] kW x 2 motors: 100-400 kW in total" in err
    code, err = _run(capsys, "pareto", cfg, "--all-topologies", "--bound", "motr_kw=5:6", "--out", tmp_path / "x", *study)
    assert code == 2 and "--bound 'motr_kw': not a design variable of any studied topology" in err


def test_instances_need_the_ros_transport_exit_2(tmp_path, capsys):
    code, err = _run(capsys, "pareto", _write(tmp_path, _raw("IWM-SA", DVS["IWM-SA"])), "--instances", "energy=2",
                     "--generations", "1", "--pop", "4", "--no-plots", "--out", tmp_path / "o", "--transport", "inprocess")
    assert code == 2 and "--instances needs --transport ros" in err and "Traceback" not in err, err


def test_instances_naming_an_unknown_discipline_exit_2(tmp_path, capsys):
    code, err = _run(capsys, "pareto", _write(tmp_path, _raw("IWM-SA", DVS["IWM-SA"])), "--transport", "ros",
                     "--instances", "warp_drive=2", "--no-plots", "--out", tmp_path / "o")
    assert code == 2 and "warp_drive" in err and "Traceback" not in err, err
    assert not (tmp_path / "o" / "bag").exists()  # refused before any node or recorder started


@pytest.mark.parametrize("change, thesis", [({}, True), ({"load_kg": 300.0, "glider_kg": 2100.0}, False),
                                            ({"drag_area_m2": 1.2}, False), ({"cycle": "nedc"}, False)])
def test_benchmark_csv_compares_with_table_4_5_only_for_the_thesis_vehicle(change, thesis, tmp_path):
    """benchmark.csv put Table 4-5's Leaf (thesis_*) beside any vehicle's benchmark design, and took
    the kerb mass as the vehicle mass less the Leaf's 69 kg load."""
    from bev_mdo.config import RunConfig
    from bev_mdo.studies.topologies import THESIS_4_5, write_benchmark

    raw = yaml.safe_load(ARTEMIS.read_text())
    if "cycle" in change:
        raw["cycle"] = {"name": change.pop("cycle"), "dt_s": 1.0}
    raw["vehicle"].update(change)
    configs = {t: RunConfig.load(config_for_topology(raw, t)) for t in ("SM-SA", "DM-DA")}
    bench = {t: {"vehicle_mass_kg": 1600.0, "accel_time_0_100_s": 9.5, "powertrain_cost_usd": 9000.0,
                 "energy_wh_per_km": 140.0} for t in configs}
    write_benchmark(tmp_path / "benchmark.csv", bench, configs)
    rows = list(csv.DictReader((tmp_path / "benchmark.csv").open()))
    assert [r["topology"] for r in rows] == ["SM-SA", "DM-DA"]
    assert float(rows[0]["kerb_kg"]) == pytest.approx(1600.0 - change.get("load_kg", 69.0))
    assert any(k.startswith("thesis_") for k in rows[0]) == thesis
    if thesis:
        assert float(rows[1]["thesis_kerb_kg"]) == THESIS_4_5["DM-DA"][0]
        assert float(rows[1]["thesis_accel_s"]) == THESIS_4_5["DM-DA"][1]


def test_a_front_with_no_feasible_design_says_so(tmp_path, capsys):
    # A two-motor trial: a topology that could not meet a 0-100 km/h constraint was reported as
    # "SM-SA: 0 non-dominated designs", as if the study had found an empty trade-off.
    raw = _raw("SM-SA")
    raw["problem"]["constraints"]["range_nedc_km"] = {"lower": 1.0e+6}  # no battery in the bounds goes that far
    code = main(["pareto", str(_write(tmp_path, raw)), "--generations", "1", "--pop", "4", "--no-plots",
                 "--out", str(tmp_path / "o"), "--transport", "inprocess"])
    out = capsys.readouterr().out
    assert code == 1  # as optimize's infeasible end
    line = next(l for l in out.splitlines() if l.startswith("front: "))
    assert line.startswith("front: no feasible design (least violated: "), line
    assert " breaks range_nedc_km >= 1e+06 km: its range_nedc_km is " in line


def test_the_topology_study_prints_its_ranking_with_its_caveats(tmp_path, capsys):
    """The study printed each topology's front and nothing to compare them by, nor that its 0-100 km/h
    times have no grip limit and its energies come from the uncalibrated thesis model."""
    out = tmp_path / "o"
    code = main([str(a) for a in ("pareto", _write(tmp_path, _raw("SM-SA")), "--all-topologies", "--generations",
                                  "1", "--pop", "4", "--no-plots", "--out", out, "--transport", "inprocess")])
    stdout = capsys.readouterr().out
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    ranked = summary["ranking"]["energy_wh_per_km"]
    assert sorted(r["topology"] for r in ranked) == ["DM-DA", "IWM-DA", "IWM-SA", "SM-SA"]
    assert [r["best"] for r in ranked] == sorted(r["best"] for r in ranked)
    assert f"ranking by each front's best energy_wh_per_km (Wh/km): {ranked[0]['topology']} " in stdout
    assert "ran on the thesis' efficiency map" in summary["caveats"][-1] and summary["caveats"][-1] in stdout


@pytest.mark.parametrize("argv, said", [
    (["--objectives", "f1,,f2"], "--objectives 'f1,,f2': an empty name; give A,B[,C]"),
    (["--objectives", "f1,"], "--objectives 'f1,': an empty name"),
    (["--topology", "SM-SA", "--topology", "DM-DA"], "--topology given twice (SM-SA and DM-DA)"),
])
def test_a_name_left_out_or_a_topology_given_twice_is_refused(argv, said, capsys, tmp_path):
    """A pareto trial: 'f1,,f2' was read as f1,f2 and a second --topology silently replaced the first."""
    srn = Path(__file__).resolve().parents[2] / "examples" / "pareto" / "srn.yaml"
    try:
        status = main(["pareto", str(ARTEMIS if "--topology" in argv else srn), *argv, "--transport", "inprocess",
                       "--out", str(tmp_path / "o")])
    except SystemExit as exc:  # argparse's error, as for any flag it refuses
        status = exc.code
    assert status == 2 and said in capsys.readouterr().err and not (tmp_path / "o").exists()


def test_a_population_too_large_for_memory_is_refused_before_anything_runs(capsys, tmp_path):
    """A pareto trial: --pop 1000000 ended in 'MemoryError: Unable to allocate 7.28 TiB', exit 7."""
    srn = Path(__file__).resolve().parents[2] / "examples" / "pareto" / "srn.yaml"
    assert main(["pareto", str(srn), "--pop", "1000000", "--generations", "1", "--transport", "inprocess",
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "--pop 1000000: at most 5,000" in err and not (tmp_path / "o").exists()
