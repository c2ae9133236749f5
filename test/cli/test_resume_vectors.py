"""`resume` of a problem with vector design variables starts from the recorded iterate: it kept only
the design values whose names were the config's keys (x_2, x_3), so the elements of x_shared and x_1
(named 'x_shared[0]', ... in the bag) were dropped and the run restarted from their initial values
while the line above it said 'resuming ... at x_shared[0]=0.06, ...' (SSBJ, propane)."""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from bev_mdo.cli import main

SSBJ = Path(__file__).resolve().parents[2] / "examples" / "ssbj"


def test_resume_starts_from_every_element_of_the_recorded_design(tmp_path, capsys):
    raw = yaml.safe_load((SSBJ / "ssbj_mdf.yaml").read_text())
    raw["search_path"] = [str(SSBJ)]
    raw["optimizer"]["options"] = {"maxiter": 3}
    cfg = tmp_path / "ssbj_3.yaml"
    cfg.write_text(yaml.safe_dump(raw))
    from bev_mdo.bag.history import history, last_iterate

    old, new = tmp_path / "old", tmp_path / "new"
    # cut short by maxiter 3: never a verified optimum (5), or infeasible (1)
    assert main(["optimize", str(cfg), "--transport", "inprocess", "--bag", str(old), "--quiet"]) in (1, 5)
    main(["resume", str(old), "--transport", "inprocess", "--output", str(new), "--quiet"])
    capsys.readouterr()
    _, design, k = last_iterate(old)  # the record resume names: the run's result (maxiter cut it short)
    last, start = next(r for r in history(old) if r["iteration"] == k), history(new)[0]
    assert last["design"] == design
    assert set(start["design"]) == set(last["design"]) and "x_shared[1]" in start["design"]
    for name, value in last["design"].items():
        assert start["design"][name] == value, name
    assert start["objective"] == last["objective"]


def test_resume_names_its_own_flag_when_the_output_bag_exists(tmp_path, capsys):
    """resume --output X said '--bag X: a bag already exists there' (optimize's flag)."""
    old = tmp_path / "old"
    assert main(["optimize", str(SSBJ.parents[1] / "config" / "leaf_nedc.yaml"), "--transport", "inprocess",
                 "--bag", str(old), "--quiet"]) == 0
    capsys.readouterr()
    assert main(["resume", str(old), "--transport", "inprocess", "--output", str(old), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"--output {old}: a bag already exists there" in err and "--bag" not in err, err


def test_a_run_is_not_recorded_into_a_sweeps_output_folder(tmp_path, capsys):
    """optimize --bag and resume --output took a sweep's --out folder and wrote a second bag beside its
    bag/; bag info and history of the folder then read the new 2-record bag and the sweep was hidden."""
    leaf = str(SSBJ.parents[1] / "config" / "leaf_nedc.yaml")
    out = tmp_path / "sweep"
    assert main(["sweep", leaf, "--vary", "motor_kw=70,90", "--out", str(out), "--no-plots", "--transport", "inprocess"]) == 0
    capsys.readouterr()
    assert main(["optimize", leaf, "--transport", "inprocess", "--bag", str(out), "--quiet"]) == 2
    assert f"--bag {out}: a run's output folder, its bag in bag/; choose a new directory" in capsys.readouterr().err
    assert main(["resume", str(out), "--transport", "inprocess", "--output", str(out), "--quiet"]) == 2
    assert f"--output {out}: a run's output folder" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir() if p.suffix == ".mcap") == []


def test_resume_goes_on_with_the_formulation_and_optimizer_the_run_used(tmp_path, capsys):
    """An in-process run's bag stored the config's formulation and optimiser, not those of --formulation and
    --optimizer (a ROS run's did), so resuming a COBYLA IDF run went on with the config's SLSQP MDF."""
    from bev_mdo.bag.history import history, last_iterate

    raw = yaml.safe_load((SSBJ.parents[1] / "config" / "leaf_nedc.yaml").read_text())
    raw["optimizer"]["options"] = {"maxiter": 10}
    cfg = tmp_path / "leaf_10.yaml"
    cfg.write_text(yaml.safe_dump(raw))
    old, new = tmp_path / "old", tmp_path / "new"
    main(["optimize", str(cfg), "--transport", "inprocess", "--bag", str(old), "--quiet",
          "--optimizer", "COBYLA", "--formulation", "idf"])
    main(["resume", str(old), "--transport", "inprocess", "--output", str(new), "--quiet"])
    capsys.readouterr()
    assert {(r["formulation"], r["optimizer"]) for r in history(old) + history(new)} == {("idf", "COBYLA")}


def test_resume_from_an_iterate_just_outside_a_bound_starts_on_the_bound(tmp_path, capsys):
    """COBYLA ends Sellar MDF at z2=-5e-08, below its bound 0 (within the feasibility tolerance, so its
    result); resume refused that start: 'x0 z2=-5e-08 is outside the bounds [0, 10]' (exit 2)."""
    from bev_mdo.bag.history import history, last_iterate

    cfg = SSBJ.parents[0] / "sellar" / "sellar_mdf.yaml"
    old, new = tmp_path / "old", tmp_path / "new"
    main(["optimize", str(cfg), "--optimizer", "COBYLA", "--transport", "inprocess", "--bag", str(old), "--quiet"])
    if not history(old)[-1]["design"]["z2"] < 0:  # the case: the bag's last iterate lies outside [0, 10]
        pytest.skip("COBYLA ended inside the bounds on this host")
    capsys.readouterr()
    assert main(["resume", str(old), "--transport", "inprocess", "--output", str(new), "--quiet"]) != 2
    z2 = history(old)[-1]["design"]["z2"]
    assert f"starting on the bound of z2 (recorded {z2:.12g}, {-z2:.3g} below its lower bound 0)" \
        in capsys.readouterr().out  # it read "z2 (-5e-08 -> 0)", and "(20 -> 20)" 3e-10 below a bound of 20
    assert history(new)[0]["design"]["z2"] == 0.0


def test_a_start_put_on_its_bound_says_how_far_outside_it_was():
    """A multi-start's record 3e-10 below battery_kwh's bound 20 read "starting on the bound of battery_kwh
    (20 -> 20)"."""
    import io

    from bev_mdo.cli.resume import _in_bounds
    from bev_mdo.config import RunConfig, load_config

    config = load_config(str(SSBJ.parents[1] / "config" / "leaf_nedc.yaml"))
    out = io.StringIO()
    x0 = _in_bounds(config, RunConfig.of(config).problem, {"motor_kw": 80.0, "gear_ratio": 8.0, "battery_kwh": 20 - 3e-10}, out)
    assert x0["battery_kwh"] == 20.0 and out.getvalue() == (
        "starting on the bound of battery_kwh (recorded 19.9999999997, 3e-10 below its lower bound 20)\n")
