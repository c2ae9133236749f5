"""`bev-mdo sensitivity --global sobol|morris`: SALib's indices of user disciplines with published
values, and on the BEV problem the same ranking of gear ratio and motor power as the local
sensitivities.

The Sobol' checks use N = 2048 (N (D + 2) designs) and seed 1. While developing, seeds 1-20 were
run: for Ishigami every index of every seed lay within its 95 % interval of the published value;
for the G function (16 indices) 17 of the 20 seeds had all 16 within, each miss a single index
(the rate 95 % intervals give)."""
from __future__ import annotations

import json
import sys

import numpy as np
import pytest

from bev_mdo.cli import main
from bev_mdo.testing import REPO

EXAMPLES = REPO / "examples" / "sensitivity"
sys.path.insert(0, str(EXAMPLES))
from test_functions import g_indices  # noqa: E402

ISHIGAMI_S1 = [0.3139, 0.4424, 0.0]  # a = 7, b = 0.1 (Ishigami & Homma 1990; Saltelli et al. 2008)
ISHIGAMI_ST = [0.5576, 0.4424, 0.2437]


def _json(capsys, *argv) -> dict:
    """The JSON a ``bev-mdo`` command prints, run in process."""
    assert main([*map(str, argv), "--transport", "inprocess"]) == 0
    return json.loads(capsys.readouterr().out)


def _within(got, conf, published):
    return np.abs(np.asarray(got) - np.asarray(published)) <= np.asarray(conf)


def test_ishigami_sobol_indices_are_within_their_intervals_of_the_published_values(capsys):
    rep = _json(capsys, "sensitivity", EXAMPLES / "ishigami.yaml", "--global", "sobol", "--samples", 2048,
                "--seed", 1, "--json")
    assert rep["n_evaluations"] == 2048 * (3 + 2)
    r = rep["outputs"]["f"]
    assert _within(r["S1"], r["S1_conf"], ISHIGAMI_S1).all(), (r["S1"], r["S1_conf"])
    assert _within(r["ST"], r["ST_conf"], ISHIGAMI_ST).all(), (r["ST"], r["ST_conf"])
    assert max(r["S1_conf"] + r["ST_conf"]) < 0.1  # narrow enough to tell the indices apart


def test_g_function_sobol_indices_are_within_their_intervals_of_the_closed_form(capsys):
    rep = _json(capsys, "sensitivity", EXAMPLES / "g_function.yaml", "--global", "sobol", "--samples", 2048,
                "--seed", 1, "--json")
    s1, st = g_indices()
    r = rep["outputs"]["g"]
    assert _within(r["S1"], r["S1_conf"], s1).all(), (r["S1"], r["S1_conf"], s1)
    assert _within(r["ST"], r["ST_conf"], st).all(), (r["ST"], r["ST_conf"], st)


def test_g_function_morris_ranks_the_variables_by_their_a(capsys):
    """mu* falls with a_i (0, 1, 4.5, 9, then 99 four times: the unimportant ones)."""
    rep = _json(capsys, "sensitivity", EXAMPLES / "g_function.yaml", "--global", "morris", "--samples", 64,
                "--json")
    mu = np.array(rep["outputs"]["g"]["mu_star"])
    assert rep["n_evaluations"] == 64 * (8 + 1)
    assert list(np.argsort(-mu[:4])) == [0, 1, 2, 3]
    assert mu[4:].max() < 0.1 * mu[3]


def test_every_design_goes_in_one_call():
    from bev_mdo.api.sensitivity import analyse

    calls = []

    def fun(X):
        calls.append(len(X))
        return {"y": X[:, 0] + 2 * X[:, 1]}

    rep = analyse("sobol", fun, {"a": 0.5, "b": 0.5, "p": 3.0}, {"a": (0, 1), "b": (0, 1)}, ["a", "b"], ["y"],
                  256, 1, design=["a", "b"])
    assert calls == [256 * 4]
    assert rep["fixed"] == {}
    st = rep["outputs"]["y"]["ST"]
    assert st[1] > st[0]  # b counts four times as much variance (0.8 vs 0.2)


def test_on_the_bev_problem_gear_ratio_and_motor_power_rank_as_locally(capsys):
    """Energy per km (the objective) and range: the gear ratio matters more than the motor power,
    locally at the initial design (|S_i|, eq 5-4) and globally over the bounds (total index ST,
    apart by more than both intervals). (The 0-100 km/h time does NOT rank them alike: locally at
    8:1 the motor power dominates, over gear ratios 1-11 the gear ratio does.)"""
    cfg = REPO / "config" / "leaf_nedc.yaml"
    local = _json(capsys, "sensitivity", cfg, "--order", "1", "--json")
    glob = _json(capsys, "sensitivity", cfg, "--global", "sobol", "--samples", 512, "--json")
    names = glob["variables"]
    g, m = names.index("gear_ratio"), names.index("motor_kw")
    lg, lm = local["wrt"].index("gear_ratio"), local["wrt"].index("motor_kw")
    for out in ("energy_wh_per_km", "range_km"):
        s = np.abs(local["first_order"][out]["normalised"])
        assert s[lg] > s[lm], out
        r = glob["outputs"][out]
        assert r["ST"][g] - r["ST_conf"][g] > r["ST"][m] + r["ST_conf"][m], (out, r)
    assert "notes" not in glob and "at_ceiling" not in glob["outputs"]["accel_time_0_100_s"]  # every sample reaches 100 km/h


def test_samples_that_cannot_reach_100_kmh_are_counted_and_said(capsys):
    """Over gear ratios up to 16:1 some designs cannot reach 100 km/h: their 0-100 km/h times are the continuation
    value (10 000 s and up), which swamped the indices (a Bolt config: ST of motor power 3e-6, against 0.77 with
    the gear ratio kept below 10) with no word said."""
    cfg = REPO / "config" / "leaf_nedc.yaml"
    rep = _json(capsys, "sensitivity", cfg, "--global", "sobol", "--samples", 64, "--bound", "gear_ratio=1:16", "--json")
    at = rep["outputs"]["accel_time_0_100_s"]["at_ceiling"]
    assert 0 < at < rep["n_evaluations"]
    assert [n for n in rep["notes"] if n.startswith(f"accel_time_0_100_s: {at} of {rep['n_evaluations']} samples")]
    assert "at_ceiling" not in rep["outputs"]["energy_wh_per_km"]
    assert main(["sensitivity", str(cfg), "--global", "morris", "--samples", "8", "--bound", "gear_ratio=1:16",
                 "--transport", "inprocess"]) == 0
    assert "note: accel_time_0_100_s: " in capsys.readouterr().out


@pytest.mark.parametrize("argv, message", [
    (["--global", "sobol", "--samples", "1000"], "must be a power of 2"),
    (["--global", "sobol", "--samples", "0"], "--samples 0: must be >= 2"),  # 0 ran the default 1024
    (["--global", "morris", "--samples", "0"], "--samples 0: must be >= 2"),
    (["--global", "sobol", "--wrt", "drag_area_m2"], "has no bounds"),
    # a flag of the other kind was ignored without a word
    (["--order", "1", "--seed", "3"], "--seed: needs --global sobol|morris"),
    (["--samples", "8", "--conf-level", "0.5"], "--samples, --conf-level: needs --global sobol|morris"),
    (["--global", "morris", "--order", "1"], "--order: local sensitivities only (without --global)"),
    (["--global", "morris", "--at", "motor_kw=60"], "--at motor_kw: varied over the bounds by --global"),
])
def test_bad_global_input_is_one_line_exit_2(capsys, argv, message):
    assert main(["sensitivity", str(REPO / "config" / "leaf_nedc.yaml"), "--transport", "inprocess", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err


def test_the_plot_names_the_bounds_and_fixed_values(tmp_path, capsys):
    png = tmp_path / "g.png"
    assert main(["sensitivity", str(REPO / "config" / "leaf_nedc.yaml"), "--global", "morris", "--samples", "8",
                 "--wrt", "motor_kw,gear_ratio", "--png", str(png), "--transport", "inprocess"]) == 0
    assert png.stat().st_size > 1000
    out = capsys.readouterr().out
    assert "fixed at battery_kwh=24" in out


@pytest.mark.parametrize("method, samples", [("morris", "8"), ("sobol", "64")])
def test_the_tables_say_morris_units_and_keep_their_columns(capsys, method, samples):
    """A docs trial: the Morris table gave mu* with no unit (doe.md: in the output's unit), and the Sobol' table's
    columns ran out of line where a cell with its interval was wider than the column."""
    assert main(["sensitivity", str(REPO / "config" / "leaf_nedc.yaml"), "--global", method, "--samples", samples,
                 "--transport", "inprocess"]) == 0
    out = capsys.readouterr().out
    assert ("energy_wh_per_km (mu* and sigma in Wh/km)" in out) == (method == "morris"), out
    blocks = [b.splitlines()[1:] for b in out.split("\n\n")[1:] if "motor_kw" in b]
    assert blocks and all(len({len(line) for line in b}) == 1 for b in blocks), blocks
