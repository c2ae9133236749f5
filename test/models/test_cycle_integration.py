"""Drive cycles integrated as the piecewise-linear traces they are, converged
in the time step; drive-cycle input validation."""

import numpy as np
import pytest

from bev_mdo.models import breakdown, chain, flat, quasi_static as qs
from bev_mdo.models.cycles import (DriveCycle, _ECE15, _EUDC, load_cycle, nedc, quadrature, read_cycle_csv,
                                   resample)
from bev_mdo.models.params import validate_vehicle


CYCLES = ("nedc", "wltc_class3", "artemis_combined", "epa_udds", "epa_hwfet", "epa_us06")
V = validate_vehicle({})
CAL = validate_vehicle({"parameter_set": "epa2022_chain"})


def _exact_nedc_moments():
    """Exact integrals of v, v^3 and the positive inertia work of the R83 segment table."""
    dist = v3 = kin = 0.0
    for table, reps in ((_ECE15, 4), (_EUDC, 1)):
        for (t0, u0), (t1, u1) in zip(table[:-1], table[1:]):
            a, b, h = u0 / 3.6, u1 / 3.6, t1 - t0
            dist += reps * h * (a + b) / 2
            v3 += reps * h * (a + b) * (a * a + b * b) / 4  # integral of a linear v^3
            kin += reps * max(b * b - a * a, 0.0) / 2
    return dist, v3, kin


def test_nedc_from_the_regulation_table_is_integrated_exactly():
    dist, v3, kin = _exact_nedc_moments()
    r = resample(nedc(), 1.0)
    assert r.method == "linear"
    v, a, _, w = quadrature(r)
    assert np.sum(v * w) == pytest.approx(dist, rel=1e-12)            # 11.013 km
    assert np.sum(v ** 3 * w) == pytest.approx(v3, rel=1e-12)         # Gauss-Legendre 2: exact for cubics
    assert np.sum(np.maximum(a, 0) * v * w) == pytest.approx(kin, rel=1e-12)  # kinetic energy per kg
    # pchip loses inertia work at every ramp end (the issue's ~10 %)
    vp, ap, _, wp = quadrature(resample(nedc(), 1.0, "pchip"))
    assert np.sum(np.maximum(ap, 0) * vp * wp) < 0.95 * kin


def test_linear_grid_contains_every_breakpoint_of_a_non_integer_trace():
    c = DriveCycle("odd", np.array([0.0, 0.3, 2.7, 5.0]), np.array([0.0, 2.0, 2.0, 0.0]))
    r = resample(c, 1.0)
    assert set(c.time_s) <= set(np.round(r.time_s, 12))
    v, a, _, w = quadrature(r)
    assert np.sum(v * w) == pytest.approx(c.distance_m, rel=1e-12)


def _energies(r):
    m, ig, kw = np.array([1590.0, 2200.0]), np.array([8.0, 9.0]), np.array([80.0, 150.0])
    return {"flat": flat.energy_wh_per_km(r, V, m, ig),
            "breakdown": breakdown.energy_wh_per_km(r, V, m, ig, kw),
            "quasi_static": qs.energy_wh_per_km(r, V, m, ig, kw),
            "chain": chain.energy_wh_per_km(r, {**V, "aux_power_w": 300.0, "charger_efficiency": 0.9}, m, ig, kw),
            "chain_calibrated": chain.energy_wh_per_km(r, CAL, m, ig, kw)}


@pytest.mark.parametrize("name", CYCLES)
def test_energy_converged_at_the_default_step(name):
    """Halving the default 1 s step changes every model's energy by < 0.1 %."""
    c = load_cycle(name)
    e1 = _energies(resample(c))          # defaults: linear, 1 s
    e2 = _energies(resample(c, 0.5))
    for model in e1:
        np.testing.assert_array_less(np.abs(e2[model] / e1[model] - 1.0), 1e-3, err_msg=f"{name} {model}")


def test_flat_default_nedc_is_higher_than_pchip():
    """The pchip default under-read the inertia work: the linear NEDC reads ~4 % higher."""
    lin = flat.energy_wh_per_km(resample(nedc()), V, np.array([1590.0]), np.array([8.0]))[0]
    pch = flat.energy_wh_per_km(resample(nedc(), 1.0, "pchip"), V, np.array([1590.0]), np.array([8.0]))[0]
    assert 1.03 < lin / pch < 1.05


def _csv(tmp_path, rows, name="c.csv"):
    p = tmp_path / name
    p.write_text("time_s,speed_kmh\n" + "".join(f"{t},{v}\n" for t, v in rows))
    return p


@pytest.mark.parametrize("rows,match", [
    ([(0, 0), (1, 10), (1e9, 10), (1e9 + 1, 0)], r"row 4: time gap of 1e\+09 s"),
    ([(0, 0), (1, 5), (1, 6)], r"row 4: time_s must be strictly increasing"),
    ([(0, 0), (2, 5), (1, 6)], r"row 4: time_s must be strictly increasing"),
    ([(0, 0), (1, -3), (2, 0)], r"row 3: speed_kmh must be >= 0, got -3"),
    ([(0, 0), (1, 100000), (2, 0)], r"row 3: speed_kmh 100000 is not plausible"),
    ([(0, 0), (1, 150), (2, 0)], r"row 3: acceleration 41.6667 m/s\^2 is not plausible"),
    ([(0, 0), (1, 0), (2, 0)], r"does not move"),
    ([(0, 0), (1, "x")], r"row 3, column speed_kmh: not a number: 'x'"),
    # what float() reads besides: 1_0 as 10 s, inf and nan (a measured value), other scripts' digits
    ([(0, 0), ("1_0", 5), (11, 0)], r"row 3, column time_s: not a number: '1_0'"),
    ([(0, 0), (1, " inf"), (2, 0)], r"row 3, column speed_kmh: must be finite, got inf"),
    ([(0, 0), ("nan", 5), (2, 0)], r"row 3, column time_s: must be finite, got nan"),
    ([(0, 0), (1, "1e999")], r"row 3, column speed_kmh: must be finite, got 1e999"),
    ([(0, 0), (1, "\u0665")], r"row 3, column speed_kmh: not a number: '\u0665'"),
])
def test_bad_cycle_csv_one_line_naming_file_and_row(tmp_path, rows, match):
    p = _csv(tmp_path, rows)
    with pytest.raises(ValueError, match=match) as e:
        read_cycle_csv(p)
    assert str(p) in str(e.value) and "\n" not in str(e.value)


@pytest.mark.parametrize("header,got", [("time_s,speed_mph", "'time_s,speed_mph'"), ("time;speed", "'time;speed'"),
                                        ("", "nothing")])
def test_a_wrong_cycle_header_is_quoted_with_the_units_asked(tmp_path, header, got):
    """It said only "header must be 'time_s,speed_kmh'": a trace in mph, or with ';', did not say what was read."""
    p = tmp_path / "c.csv"
    p.write_text(header + "\n" if header else "")
    with pytest.raises(ValueError) as e:
        read_cycle_csv(p)
    assert f"row 1: header must be 'time_s,speed_kmh', got {got} (time in s, speed in km/h: convert mph" in str(e.value)


def test_too_many_samples_refused_before_allocating():
    c = DriveCycle("long", np.array([0.0, 3600.0, 7200.0, 1e6]), np.array([0.0, 10.0, 10.0, 0.0]))
    with pytest.raises(ValueError, match="samples"):
        resample(c, 0.01)


def test_cli_bad_cycle_exits_2_with_one_line(tmp_path, capsys):
    from pathlib import Path

    from bev_mdo.cli import main

    root = Path(__file__).resolve().parents[2]
    bad = _csv(tmp_path, [(0, 0), (1, 10), (1e9, 10), (1e9 + 1, 0)], "gap.csv")
    cfg = (root / "config" / "leaf_nedc.yaml").read_text().replace("name: nedc", f"name: {bad}")
    cp = tmp_path / "cfg.yaml"
    cp.write_text(cfg)
    code = main(["evaluate", str(cp), "--transport", "inprocess"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and "gap.csv: row 4: time gap" in err and "Traceback" not in err
