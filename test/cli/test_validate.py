"""``bev-mdo validate``: fleet table, statistics, parity plot, bad input."""
import csv
import json

import numpy as np
import pytest

from bev_mdo.cli import main
from bev_mdo.models import fleet as fl


TRAIN = fl.DEFAULT_FLEET


def run(capsys, *argv):
    code = main(["validate", *map(str, argv)])
    out = capsys.readouterr()
    return code, out.out, out.err


def _rows():
    with TRAIN.open(newline="") as f:
        return list(csv.reader(f))


def _write(tmp_path, rows, name="fleet.csv"):
    p = tmp_path / name
    with p.open("w", newline="") as f:
        csv.writer(f).writerows(rows)
    return p


def test_default_fleet_json(capsys):
    code, out, _ = run(capsys, "--json")
    assert code == 0
    doc = json.loads(out)
    assert doc["vehicles"] == 62 and doc["energy_model"] == "quasi_static"
    assert doc["parameter_set"] == "epa2022_quasi_static"  # the default: the lowest held-out error
    s = doc["stats"]
    assert s["udds"]["n"] == s["hwfet"]["n"] == 62 and s["udds_hwfet"]["n"] == 124
    errs = np.array([r[f"{c}_error_pct"] for r in doc["rows"] for c in ("udds", "hwfet")])
    assert s["udds_hwfet"]["mean_abs_pct"] == pytest.approx(np.abs(errs).mean())
    assert s["udds_hwfet"]["p90_abs_pct"] == pytest.approx(np.percentile(np.abs(errs), 90))
    r0 = doc["rows"][0]
    assert r0["row"] == 2 and r0["udds_measured_wh_per_km"] == pytest.approx(133.99)
    assert r0["udds_error_pct"] == pytest.approx(100 * (r0["udds_predicted_wh_per_km"] / 133.99 - 1))


def test_errors_by_make(capsys, tmp_path):
    """Each make's statistics over its scored vehicle-cycles, most over-predicted first; a vehicle
    that cannot follow is not in them (as in the fleet-wide figures)."""
    code, out, _ = run(capsys, "--json")
    doc = json.loads(out)
    by = doc["by_make"]
    assert sum(r["n"] for r in by) == doc["stats"]["udds_hwfet"]["n"]
    signed = [r["mean_signed_pct"] for r in by]
    assert signed == sorted(signed, reverse=True)
    tesla = [r[f"{c}_error_pct"] for r in doc["rows"] if r["make"] == "Tesla" for c in ("udds", "hwfet")]
    (t,) = [r for r in by if r["make"] == "Tesla"]
    assert t["vehicles"] == 13 and t["mean_signed_pct"] == pytest.approx(np.mean(tesla))
    assert t["mean_abs_pct"] == pytest.approx(np.mean(np.abs(tesla)))
    rows = _rows()
    i = next(k for k, r in enumerate(rows) if r[0] == "Tesla")
    rows[i][rows[0].index("rated_power_kw")] = "5"  # this one cannot follow: left out of Tesla's figures
    code, out, _ = run(capsys, "--data", _write(tmp_path, rows), "--json")
    (t5,) = [r for r in json.loads(out)["by_make"] if r["make"] == "Tesla"]
    assert t5["vehicles"] == 13 and t5["n"] < 26
    code, out, _ = run(capsys)
    first = by[0]  # the most over-predicted make leads the line
    assert f"by make, both cycles (mean signed % / mean |err| %): {first['make']} {first['mean_signed_pct']:+.1f} / " in out


def test_table_and_parity_plot(capsys, tmp_path):
    plots = tmp_path / "new" / "plots"  # created
    code, out, _ = run(capsys, "--plot", plots)
    assert code == 0
    assert "udds_hwfet: n=124" in out and "P90" in out and "Mach-E RWD" in out
    png = plots / "parity.png"
    assert png.stat().st_size > 10_000 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in plots.iterdir()) == ["parity.png"]  # the pairs plots only with --pairs


@pytest.mark.parametrize("model", ["flat", "breakdown", "chain", "topology_sm_sa"])
def test_every_energy_model_validates(capsys, model):
    code, out, _ = run(capsys, "--energy-model", model, "--json")
    doc = json.loads(out)
    calibrated = {"chain": "epa2022_chain", "topology_sm_sa": "epa2022_quasi_static"}.get(model)
    assert code == 0 and doc["energy_model"] == model and doc["parameter_set"] == calibrated
    assert np.isfinite(doc["stats"]["udds_hwfet"]["mean_abs_pct"])


def test_a_vehicle_that_cannot_follow_is_reported_not_scored(capsys, tmp_path):
    rows = _rows()
    h = rows[0]
    rows[1][h.index("rated_power_kw")] = "15"   # a 15 kW motor in a 2268 kg car
    code, out, _ = run(capsys, "--data", _write(tmp_path, rows), "--json")
    doc = json.loads(out)
    assert code == 0
    assert {"row": 2, "cycle": "epa_udds"} in doc["not_following"]
    assert doc["rows"][0]["udds_follows"] is False
    assert doc["stats"]["udds"]["n"] == 61
    code, out, _ = run(capsys, "--data", _write(tmp_path, rows))
    assert "CANNOT FOLLOW" in out


def test_outlier_rows_are_not_scored(capsys, tmp_path):
    rows = _rows()
    rows[3][rows[0].index("flag")] = "energy inconsistent"
    doc = json.loads(run(capsys, "--data", _write(tmp_path, rows), "--json")[1])
    assert doc["rows"][2]["outlier"] is True and doc["stats"]["udds_hwfet"]["n"] == 122



def test_a_fleet_with_every_row_flagged_is_refused_as_calibrate_refuses_it(capsys, tmp_path):
    """Every row flagged as outlier: 'n=  0 mean |err| - %' on every line and exit 0 (calibrate: exit 2)."""
    rows = _rows()[:6]
    for r in rows[1:]:
        r[rows[0].index("flag")] = "x"
    p = _write(tmp_path, rows)
    code, out, err = run(capsys, "--data", p)
    assert code == 2 and out == "" and err.count("\n") == 1
    assert f"{p}: no vehicle to score (5 of 5 flagged as outliers, 0 cannot follow UDDS or HWFET)" in err

def _bad(tmp_path, edit):
    rows = _rows()
    edit(rows)
    return _write(tmp_path, rows)


def _set(col, value, row=1):
    def f(rows):
        rows[row][rows[0].index(col)] = value
    return f


def _rename(col, new):
    def f(rows):
        rows[0][rows[0].index(col)] = new
    return f


def _drop(col):
    def f(rows):
        i = rows[0].index(col)
        for r in rows:
            del r[i]
    return f


def _duplicate(col, value):
    def f(rows):
        rows[0].append(col)
        for r in rows[1:]:
            r.append(value)
    return f


def _append_copy(row, change=None):
    def f(rows):
        copy = list(rows[row])
        if change:
            at = rows[0].index(change[0])
            copy[at] = change[1](copy[at]) if callable(change[1]) else change[1]
        rows.append(copy)
    return f


@pytest.mark.parametrize("edit,expect", [
    (_drop("test_mass_kg"), "row 1: missing column test_mass_kg"),
    (_rename("test_mass_kg", "test_mass_lb"), "row 1, column test_mass_lb: unknown unit (expected column test_mass_kg)"),
    # 'missing column udds_wh_per_km_ac' / 'missing column make' did not name the column given instead
    (_rename("udds_wh_per_km_ac", "udds_wh_per_mi_ac"),
     "row 1, column udds_wh_per_mi_ac: unknown column (expected column udds_wh_per_km_ac)"),
    (_rename("make", "Make"), "row 1, column Make: unknown column (expected column make)"),
    (_set("road_load_a_n", "abc", 5), "row 6, column road_load_a_n: not a number: 'abc'"),
    (_set("test_mass_kg", "-2000", 2), "row 3, column test_mass_kg: must not be negative"),
    (_set("udds_wh_per_km_ac", "nan", 2), "row 3, column udds_wh_per_km_ac: must be finite"),
    (_set("reported_unit", "mpg", 4), "row 5, column reported_unit: unknown unit 'mpg'"),
    (_set("rated_power_kw", "", 7), "row 8, column rated_power_kw: not a number: ''"),
    # what float() reads besides: 1_590 as 1590 kg, inf, other scripts' digits
    (_set("test_mass_kg", "1_590", 2), "row 3, column test_mass_kg: not a number: '1_590'"),
    (_set("rated_power_kw", " inf", 4), "row 5, column rated_power_kw: must be finite, got inf"),
    (_set("road_load_c_n_per_m2_s2", "\u0660.4", 6), "row 7, column road_load_c_n_per_m2_s2: not a number: '\u0660.4'"),
    (_set("road_load_b_n_per_m_s", "-40", 7), "row 8, column road_load_b_n_per_m_s: the road load"),
    # a second test_mass_kg column (e.g. pasted in lb) was read instead of the first, without a word
    (_duplicate("test_mass_kg", "5000"), "row 1, column test_mass_kg: given twice (columns 8 and 22)"),
    # a row listed twice was counted twice, weighted twice by calibrate and paired with its copy
    (_append_copy(4), "row 64: repeats row 5 (the same vehicle listed twice)"),
    # ... and so was one typed otherwise (a calibration trial: 2041.20 for 2041.2, the model in capitals)
    (_append_copy(4, ("test_mass_kg", lambda c: f"{float(c):.3f}")), "row 64: repeats row 5 (the same vehicle"),
    (_append_copy(4, ("model", str.upper)), "row 64: repeats row 5 (the same vehicle listed twice)"),
])
def test_bad_fleet_file_one_line_exit_2(capsys, tmp_path, edit, expect):
    p = _bad(tmp_path, edit)
    code, out, err = run(capsys, "--data", p)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and expect in err and str(p) in err and "Traceback" not in err


def test_one_vehicle_test_listed_twice_with_other_values_is_noted(capsys, tmp_path):
    """Not refused (EPA may list one tested vehicle under two model names), but not silent either."""
    p = _bad(tmp_path, _append_copy(4, ("udds_wh_per_km_ac", "150.0")))
    code, out, err = run(capsys, "--data", p)
    assert code == 0, err
    assert "note: " in err and "row 64: test_vehicle_id FK96493 with config 1 is also row 5" in err, err


def test_missing_file_exit_2(capsys, tmp_path):
    code, _, err = run(capsys, "--data", tmp_path / "none.csv")
    assert code == 2 and "cannot read fleet file" in err


def test_a_fleet_file_saved_by_excel_with_a_bom_and_crlf_reads_like_the_shipped_one(capsys, tmp_path):
    """Excel's "CSV UTF-8" starts the file with a byte-order mark; it must not become part of the
    first column's name (it was: "row 1: missing column make")."""
    p = tmp_path / "excel.csv"
    p.write_bytes(b"\xef\xbb\xbf" + TRAIN.read_bytes().replace(b"\n", b"\r\n"))
    code, out, err = run(capsys, "--data", p, "--json")
    assert code == 0, err
    doc, ref = json.loads(out), json.loads(run(capsys, "--json")[1])
    assert doc["vehicles"] == 62 and doc["rows"][0]["make"] == "BMW"
    assert doc["stats"] == ref["stats"]


def test_plot_into_a_file_is_one_line_exit_2(capsys, tmp_path):
    """--plot takes a folder; an existing file given by mistake is named and left alone."""
    f = tmp_path / "parity.png"
    f.write_bytes(b"mine")
    code, out, err = run(capsys, "--plot", f)
    assert code == 2 and err.count("\n") == 1 and "not a directory" in err and str(f) in err
    assert "Traceback" not in err and f.read_bytes() == b"mine"


@pytest.mark.parametrize("content,expect", [
    # csv's field limit raised _csv.Error out of read_fleet: a traceback
    (lambda raw: raw.replace(b"BMW", b"B" * 200_000, 1), "row 2: not a CSV table: field larger than field limit"),
    # UTF-16 without a BOM decodes as UTF-8 with NULs: it said "row 1: missing column rated_power_kw"
    (lambda raw: raw.decode().encode("utf-16-le"), "not a UTF-8 text CSV (NUL bytes"),
    # a quote left open merged row 2 with row 3 (61 of 62 vehicles, row 3's values under row 2's name): exit 0
    (lambda raw: raw.replace(b'(18"" Wheels)"', b'(18 Wheels)', 1),
     "row 2: a field runs over a line break into row 3 (a quote left open?)"),
    (lambda raw: raw.replace(b'(18"" Wheels)', b'(18""\nWheels)', 1), "row 2: a field runs over a line break into row 3"),
    (lambda raw: raw + b'BMW,"i4', "row 64: a quote left open (the file ends inside its field)"),
    # a quote closed inside a field was kept as a character, the rest of the field glued on
    (lambda raw: raw.replace(b'(18"" Wheels)', b'(18" Wheels)', 1), "row 2: not a CSV table: ',' expected after"),
])
def test_a_file_that_is_not_a_csv_table_is_one_line(capsys, tmp_path, content, expect):
    p = tmp_path / "odd.csv"
    p.write_bytes(content(TRAIN.read_bytes()))
    code, out, err = run(capsys, "--data", p)
    assert code == 2 and out == "" and err.count("\n") == 1 and expect in err and "Traceback" not in err


@pytest.mark.parametrize("sep", [";", "\t"])
def test_a_file_separated_by_semicolons_or_tabs_says_so(capsys, tmp_path, sep):
    """Excel's "CSV" in a locale with decimal commas separates by ';': the one-column header was
    reported as 'row 1: missing column rated_power_kw' although the header names it."""
    p = tmp_path / "semi.csv"
    with p.open("w", newline="") as f:
        csv.writer(f, delimiter=sep).writerows(_rows())
    code, out, err = run(capsys, "--data", p)
    assert code == 2 and out == "" and err.count("\n") == 1
    assert "row 1: the columns are separated by" in err and "missing column" not in err


def test_pairs_json_table_and_png(capsys, tmp_path):
    """--pairs: every pair's measured and predicted difference per cycle under one key, the slope
    and mean absolute difference recomputed from the rows, the table and the pairs plot."""
    code, out, _ = run(capsys, "--pairs", "--json", "--plot", tmp_path)
    assert code == 0
    doc = json.loads(out)
    p = doc["pairs"]
    assert p["pairs"] > 0 and "through the origin" in p["slope"]
    by_row = {r["row"]: r for r in doc["rows"]}
    for c in ("udds", "hwfet"):
        s = p[c]
        assert s["n"] == len(s["rows"]) == p["pairs"]  # no outlier and every vehicle follows
        x = np.array([r["measured_pct"] for r in s["rows"]])
        y = np.array([r["predicted_pct"] for r in s["rows"]])
        assert s["slope_through_origin"] == pytest.approx(x @ y / (x @ x))
        assert s["mean_abs_diff_points"] == pytest.approx(np.mean(np.abs(y - x)))
        assert s["slope_met"] == (0.85 <= s["slope_through_origin"] <= 1.15)
        assert s["mean_abs_diff_met"] == (s["mean_abs_diff_points"] <= 2.5)
        r = s["rows"][0]
        a, b = by_row[r["a_row"]], by_row[r["b_row"]]
        assert r["a_row"] < r["b_row"] and a["make"] == b["make"]
        for kind in ("measured", "predicted"):  # percent of the pair's mean
            ea, eb = a[f"{c}_{kind}_wh_per_km"], b[f"{c}_{kind}_wh_per_km"]
            assert r[f"{kind}_pct"] == pytest.approx(200 * (eb - ea) / (ea + eb))
    for name in ("parity.png", "pairs_udds.png", "pairs_hwfet.png"):
        assert (tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    code, out, _ = run(capsys, "--pairs")
    assert code == 0 and "within-family pairs" in out and "Mach-E RWD" in out
    # the header says what is printed: percent of the pair's mean (it said 'B over A, %')
    assert "meas% and pred%: 200 (E_B - E_A) / (E_A + E_B)" in out and "B over A" not in out
    assert "pairs  udds: n=" in out and "pairs hwfet: n=" in out and "slope" in out and "points" in out
    assert ("(target 0.85-1.15: met)" in out) or ("(target 0.85-1.15: NOT met)" in out)
    assert "pairs" not in json.loads(run(capsys, "--json")[1])  # only when asked


def test_a_fleet_without_pairs_says_so_in_one_line(capsys, tmp_path):
    rows = _rows()
    one_per_family = [rows[0]] + [r for r in rows[1:] if r[0] == "BMW" and r[1].startswith("MINI")] + \
        [r for r in rows[1:] if r[1] == "R1S"]  # R1S twice, same spec: not a pair
    p = _write(tmp_path, one_per_family)
    code, out, err = run(capsys, "--data", p, "--pairs")
    assert code == 0 and "Traceback" not in err
    lines = [ln for ln in out.splitlines() if ln.startswith("pairs")]
    assert lines == [f"pairs: none in {p} (no two rows of one model family differ in drive, rated power or test mass)"]
    doc = json.loads(run(capsys, "--data", p, "--pairs", "--json")[1])
    assert doc["pairs"]["pairs"] == 0 and doc["pairs"]["udds"]["n"] == 0
    assert doc["pairs"]["udds"]["slope_through_origin"] is None


def test_the_model_is_beside_the_baseline_and_fastsim_on_the_same_rows(capsys, tmp_path):
    """Every run: the model, the held-out 3-constant baseline and FASTSim 2.1.5 (shipped results),
    per cycle on the rows all of them score, with MAPE and pair metrics; each row carries the two
    reference predictions. A fleet FASTSim was not run on says so and keeps the other two."""
    doc = json.loads(run(capsys, "--json")[1])
    ref = doc["reference"]
    assert ref["fastsim"] == "available" and set(ref["columns"]) == {"quasi_static", "baseline3", "fastsim"}
    for c in ("udds", "hwfet"):
        t = ref["same_rows"][c]
        assert t["rows"] == 62 and t["pairs"] == 105
        for name in ("quasi_static", "baseline3", "fastsim"):
            assert np.isfinite([t[name]["mape_pct"], t[name]["pair_slope"], t[name]["pair_mad_points"]]).all()
        errs = [abs(r[f"{c}_predicted_wh_per_km"] / r[f"{c}_measured_wh_per_km"] - 1) for r in doc["rows"]]
        assert t["quasi_static"]["mape_pct"] == pytest.approx(100 * np.mean(errs))
        errs = [abs(r[f"{c}_baseline3_wh_per_km"] / r[f"{c}_measured_wh_per_km"] - 1) for r in doc["rows"]]
        assert t["baseline3"]["mape_pct"] == pytest.approx(100 * np.mean(errs))
    out = run(capsys)[1]
    assert "beside the references, same rows (FASTSim: available)" in out and "baseline3 " in out
    rows = _rows()
    ford = [r[:1] + [f"Renamed {r[1]}"] + r[2:] for r in rows[1:] if r[0] == "Ford"]  # vehicles FASTSim never ran
    doc = json.loads(run(capsys, "--data", _write(tmp_path, [rows[0]] + ford), "--json")[1])
    assert doc["reference"]["fastsim"].startswith("unavailable: FASTSim was not run on this fleet file")
    # one model family: no baseline3 figure either, so the model is scored alone on its rows
    assert doc["reference"]["baseline3"].startswith("none") and doc["reference"]["same_rows"]["udds"]["rows"] > 0
    assert set(doc["reference"]["same_rows"]["udds"]) == {"rows", "pairs", "quasi_static"}
    rows = _rows()
    rows[4][rows[0].index("road_load_c_n_per_m2_s2")] = "0.2"  # an edited copy: FASTSim ran the original row
    doc = json.loads(run(capsys, "--data", _write(tmp_path, rows), "--json")[1])
    assert doc["reference"]["fastsim"].startswith("run on 61 of 62 rows")
    assert doc["reference"]["same_rows"]["udds"]["rows"] == 61


def test_a_parameter_set_fitted_for_another_model_is_one_line_exit_2(capsys):
    """The chain's constants on the quasi-static model predicted the fleet 77 % high without a word
    (bev-mdo validate --parameter-set epa2022_chain, once the default model became quasi_static)."""
    code, out, err = run(capsys, "--parameter-set", "epa2022_chain")
    assert code == 2 and out == "" and err.count("\n") == 1
    assert "'epa2022_chain' was fitted for energy model chain, not quasi_static: give --energy-model chain" in err
    code, out, err = run(capsys, "--energy-model", "quasi_static", "--parameter-set", "thesis", "--json")
    assert code == 0 and json.loads(out)["parameter_set"] == "thesis"  # not tied to one model
    code, out, _ = run(capsys, "--energy-model", "topology_sm_sa", "--parameter-set", "epa2022_quasi_static", "--json")
    assert code == 0 and json.loads(out)["parameter_set"] == "epa2022_quasi_static"  # SM-SA is the quasi-static model
    # flat and breakdown ignored --parameter-set without a word (the JSON said parameter_set: null)
    code, out, err = run(capsys, "--energy-model", "flat", "--parameter-set", "epa2022_quasi_static")
    assert code == 2 and "fitted for energy model quasi_static, not flat" in err
    code, out, _ = run(capsys, "--energy-model", "flat", "--parameter-set", "thesis", "--json")
    assert code == 0 and json.loads(out)["parameter_set"] == "thesis"


def test_a_fleet_without_technology_columns_is_noted_with_what_is_assumed(capsys, tmp_path):
    """A fleet file without the technology columns was taken without a word while the models fell back to
    defaults. validate and calibrate now say which columns are missing and what is assumed, once, and the
    predictions are exactly those of the file with those columns filled with what the note says."""
    rows = _rows()
    header = rows[0]
    tech = [header.index(c) for c in fl.TECHNOLOGY]
    bare = _write(tmp_path, [[c for j, c in enumerate(r) if j not in tech] for r in rows], "bare.csv")
    drive = header.index("drive")
    filled = {"driven_axles": lambda r: "2" if r[drive] in ("A", "4", "P") else "1", "driven_axle_position":
              lambda r: "unknown", "motor_front": lambda r: "PMSM", "motor_rear": lambda r: "PMSM",
              "gear_count": lambda r: "1", "battery_voltage_class_v": lambda r: "unknown"}
    assumed = _write(tmp_path, [header] + [[filled[h](r) if h in filled else c for h, c in zip(header, r)]
                                            for r in rows[1:]], "assumed.csv")
    code, out, err = run(capsys, "--data", bare, "--json", "--pairs")
    assert code == 0 and err.count("\n") == 1, err
    assert err == (f"bev-mdo validate: note: {bare}: no technology columns driven_axles, driven_axle_position, "
                   "motor_front, motor_rear, gear_count, battery_voltage_class_v; assumed: driven axles from the "
                   "drive column (A, 4, P: two; else one); every machine permanent-magnet (no induction or "
                   "wound-rotor loss); one gear (no two-speed loss); within-family pairs not split by pack voltage "
                   "(400 / 800 V) (driven_axle_position is not a model input)\n")
    code, out_assumed, err = run(capsys, "--data", assumed, "--json", "--pairs")
    assert code == 0 and err == ""
    got, want = json.loads(out), json.loads(out_assumed)
    assert [r["udds_predicted_wh_per_km"] for r in got["rows"]] == [r["udds_predicted_wh_per_km"] for r in want["rows"]]
    assert got["pairs"] == want["pairs"] and got["stats"] == want["stats"]
    # one column missing: only it is named; calibrate says it too (one model family: the fit alone, fast)
    gears = header.index("gear_count")
    no_gears = _write(tmp_path, [[c for j, c in enumerate(r) if j != gears] for r in rows
                                 if r is header or r[1].startswith("i4")], "no_gears.csv")
    assert main(["calibrate", "--model", "chain", "--data", str(no_gears)]) == 0
    err = capsys.readouterr().err
    assert err == (f"bev-mdo calibrate: note: {no_gears}: no technology column gear_count; assumed: one gear "
                   "(no two-speed loss)\n"), err


def test_one_vehicle_is_one_vehicle(capsys, tmp_path):
    """The table's first line said '1 vehicles'."""
    code, out, _ = run(capsys, "--data", _write(tmp_path, _rows()[:2]))
    assert code == 0 and ": 1 vehicle, energy model" in out.splitlines()[0]
    code, out, _ = run(capsys, "--data", _write(tmp_path, _rows()[:3]))
    assert code == 0 and ": 2 vehicles, energy model" in out.splitlines()[0]


def test_the_baselines_label_says_the_folds_it_used(capsys, tmp_path):
    """A fleet of 4 families printed 'baseline3: held out, 5 folds by family' while calibrate on it said k=4:
    there are at most as many folds as families."""
    rows = _rows()
    data = _write(tmp_path, [rows[0], *(r for r in rows[1:] if r[0] in ("Ford", "KIA"))])
    families = len(set(fl.read_fleet(data).family()))
    assert 2 <= families < 5
    code, out, _ = run(capsys, "--data", data)
    assert code == 0 and f"baseline3: held out, {families} folds by family;" in out
    code, out, _ = run(capsys, "--data", data, "--json")
    doc = json.loads(out)["reference"]
    assert doc["baseline3_folds"] == families and f"({families}-fold by family)" in doc["columns"]["baseline3"]


def test_what_the_model_column_compares_is_said_alike_in_json_and_on_the_plot(capsys, tmp_path, monkeypatch):
    """With epa2022_quasi_static the predictions are wall energy (battery / charger_efficiency): the JSON's
    top-level 'compared' said so, but reference.columns.quasi_static said 'battery energy ... no charger loss',
    and parity.png's y axis read 'predicted battery energy' (only the chain was called 'wall')."""
    from bev_mdo.cli import validate_plots

    labels = {}
    monkeypatch.setattr(validate_plots, "_save", lambda fig, path: labels.update({path.parent.name: fig.axes[0]
                                                                                  .get_ylabel()}))
    data = _write(tmp_path, _rows()[:4])
    for ps, where in (("epa2022_quasi_static", "wall"), ("none", "battery")):
        code, out, _ = run(capsys, "--data", data, "--parameter-set", ps, "--json", "--plot", tmp_path / ps)
        doc = json.loads(out)
        assert code == 0 and doc["reference"]["columns"]["quasi_static"] == doc["compared"]
        assert f"predicted {where} energy" in doc["compared"]
        assert labels[ps] == f"predicted {where} energy (Wh/km)"


def test_the_footnote_says_what_the_parameter_set_was_fitted_on_and_the_model_keeps_its_figures(capsys, tmp_path):
    """The footnote said 'a parameter set fitted on these rows is in-sample' whatever ran: flat (no set) and a
    set fitted on other rows alike. And a fleet of one family, where the 3-constant baseline has no figure,
    printed no figure of the model or FASTSim either."""
    import hashlib

    import yaml

    from bev_mdo.models.params import PARAMETER_SET_DIR

    rows = _rows()
    bmw = _write(tmp_path, [rows[0], *(r for r in rows[1:] if r[0] == "BMW")], "bmw.csv")
    kia = _write(tmp_path, [rows[0], *(r for r in rows[1:] if r[0] == "KIA")], "kia.csv")
    both = _write(tmp_path, [rows[0], *(r for r in rows[1:] if r[0] in ("BMW", "KIA"))], "both.csv")
    doc = yaml.safe_load((PARAMETER_SET_DIR / "epa2022_quasi_static.yaml").read_text())
    doc["fitted_on"] = {"file": "bmw.csv", "path": str(bmw), "sha256": hashlib.sha256(bmw.read_bytes()).hexdigest()}
    mine = tmp_path / "on_bmw.yaml"
    mine.write_text(yaml.safe_dump(doc))

    def footnote(*argv):
        code, out, _ = run(capsys, *argv)
        assert code == 0
        return out.splitlines()[-1]

    assert "not refitted: no parameter set: the model's own constants" in footnote("--data", kia, "--energy-model",
                                                                                    "flat")
    assert f"parameter set {mine} was fitted on this file: in-sample" in footnote("--data", bmw,
                                                                                  "--parameter-set", mine)
    assert f"was fitted on {bmw} (not this file), which has none of these cars: held out" in footnote(
        "--data", kia, "--parameter-set", mine)
    n_bmw = len(fl.read_fleet(bmw))
    assert f"{n_bmw} of these {len(fl.read_fleet(both))} rows are cars in it" in footnote(
        "--data", both, "--parameter-set", mine)
    # the same cars with their measured energies in Wh/mi (x 1.609): in the fit, not 'held out'
    whmi = [rows[0], *([*r[:11], *(f"{float(x) * 1.609:.2f}" for x in r[11:13]), *r[13:]] for r in rows[1:]
                       if r[0] == "BMW")]
    assert rows[0][11:13] == ["udds_wh_per_km_ac", "hwfet_wh_per_km_ac"]
    assert f"{n_bmw} of these {n_bmw} rows are cars in it ({n_bmw} by make, model and model inputs" in footnote(
        "--data", _write(tmp_path, whmi, "bmw_whmi.csv"), "--parameter-set", mine)
    assert "parameter set thesis: constants not fitted to a fleet" in footnote("--data", kia, "--parameter-set",
                                                                              "thesis")
    code, out, _ = run(capsys, "--data", kia, "--parameter-set", mine)  # one family: no baseline3
    lines = out.splitlines()
    assert "baseline3: none" in lines[-4] and "; baseline3: none;" in lines[-1]
    assert lines[-3].startswith("  udds (4 rows") and "quasi_static " in lines[-3] and "fastsim " in lines[-3]
    ref = json.loads(run(capsys, "--data", kia, "--parameter-set", mine, "--json")[1])["reference"]
    assert ref["baseline3"].startswith("none") and ref["same_rows"]["hwfet"]["rows"] == 4


def test_the_parity_plots_legends_cover_no_point(capsys, tmp_path, monkeypatch):
    """parity.png's legends sat in the lower right of each panel: on the residual-vs-mass panel one covered the
    worst points (the Audi e-tron S at 2948 kg, -17 %). No legend may lie over a point of any panel."""
    from bev_mdo.cli import validate_plots

    figs = []
    monkeypatch.setattr(validate_plots, "_save", lambda fig, path: (fig.tight_layout(), figs.append(fig)))
    assert run(capsys, "--plot", tmp_path)[0] == 0
    (fig,) = [f for f in figs if len(f.axes) == 3 and f.axes[1].get_title() == "residual vs test mass"]
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:
        box = ax.get_legend().get_window_extent(renderer)
        points = np.concatenate([c.get_offset_transform().transform(c.get_offsets()) for c in ax.collections
                                 if len(c.get_offsets())])
        inside = (points[:, 0] >= box.x0) & (points[:, 0] <= box.x1) & (points[:, 1] >= box.y0) & (points[:, 1] <= box.y1)
        assert not inside.any(), (ax.get_title(), points[inside])


def _edited(tmp_path, name, pick, **edit):
    """The training rows ``pick`` takes, each cell named in ``edit`` replaced by edit[name](cell)."""
    rows = _rows()
    at = {h: i for i, h in enumerate(rows[0])}
    out = [list(r) for r in rows[1:] if pick(r)]
    for r in out:
        for col, f in edit.items():
            r[at[col]] = f(r[at[col]])
    return _write(tmp_path, [rows[0], *out], name)


def test_training_cars_re_typed_are_in_sample_and_another_car_is_held_out(capsys, tmp_path):
    """The shipped set's own cars with A rounded to 0.1 N, the test id prefixed 'X' or the test mass + 1 kg
    were said 'fitted on train.csv, which has none of these cars: held out' beside an in-sample MAPE."""
    def fitted_on(path):
        code, out, _ = run(capsys, "--data", path, "--json")
        assert code == 0
        return json.loads(out)["parameter_set_fitted_on"]

    bmw = lambda r: r[0] == "BMW"  # noqa: E731
    n = sum(map(bmw, _rows()[1:]))
    plus = lambda k: (lambda c: f"{float(c) + k:g}")  # noqa: E731
    retyped = _edited(tmp_path, "retyped.csv", bmw, road_load_a_n=lambda c: f"{float(c):.1f}",
                      test_vehicle_id=lambda c: "X" + c, test_mass_kg=plus(1), make=str.lower)
    said = fitted_on(retyped)
    assert f"(not this file); {n} of these {n} rows are cars in it ({n} by make, model and model inputs" in said
    # another mass (40 kg) under a renamed test, the same measured energies: the same car, by its energies
    heavier = _edited(tmp_path, "heavier.csv", bmw, test_vehicle_id=lambda c: "X" + c, test_mass_kg=plus(40))
    assert f"{n} of these {n} rows are cars in it ({n} by their measured UDDS and HWFET energies alone, within " \
           "0.1 %)" in fitted_on(heavier)
    # a near-duplicate that is another car: 40 kg heavier and 2 % more energy on both cycles
    other = _edited(tmp_path, "other.csv", bmw, test_vehicle_id=lambda c: "X" + c, test_mass_kg=plus(40),
                    udds_wh_per_km_ac=lambda c: f"{float(c) * 1.02:.2f}",
                    hwfet_wh_per_km_ac=lambda c: f"{float(c) * 1.02:.2f}")
    assert fitted_on(other).endswith("which has none of these cars: held out")
    half = _write(tmp_path, [*_rows()[:1], *list(csv.reader(retyped.open()))[1:4], *list(csv.reader(other.open()))[4:]],
                  "half.csv")
    assert "; 3 of these " in fitted_on(half)


def test_a_fleet_in_wh_per_mile_is_noted_once_by_the_calibrated_models(capsys, tmp_path):
    """Efficient cars in Wh/mi (their medians within the plausible band) read -34 to -40 % on every make with
    no note; the same cars in Wh/km, and the thesis constants (not fitted), give none."""
    efficient = lambda r: float(r[11]) < 160 and float(r[12]) < 160  # noqa: E731
    whmi = _edited(tmp_path, "whmi.csv", efficient, udds_wh_per_km_ac=lambda c: f"{float(c) * 1.609:.2f}",
                   hwfet_wh_per_km_ac=lambda c: f"{float(c) * 1.609:.2f}")
    for model in ("quasi_static", "chain"):
        code, _, err = run(capsys, "--data", whmi, "--energy-model", model)
        assert code == 0 and err.count("note:") == 1, err
        assert f"whmi.csv: {model} predicts 0.6" in err
        assert "likely a unit mix-up, measured energies in Wh per mile (1.609 x Wh/km)?" in err
    assert "note:" not in run(capsys, "--data", whmi, "--parameter-set", "thesis")[2]
    wh_km = _edited(tmp_path, "whkm.csv", efficient)
    assert "note:" not in run(capsys, "--data", wh_km)[2]
