"""The sensitivity figure, inspected: first-order bars, one symmetric colour scale for every
matrix, entries not above their error masked, readable text colour, point and cycle in the title."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from bev_mdo.api.sensitivity import build_batch
from bev_mdo.cli.sensitivity import write_heatmap
from bev_mdo.config import load_config, resolve_disciplines
from bev_mdo.mdo.evaluator import InProcessEvaluator
from bev_mdo.mdo.sensitivity import sensitivities

ROOT = Path(__file__).resolve().parents[2]


def test_sensitivity_figure(tmp_path):
    cfg = load_config(str(ROOT / "config/leaf_nedc.yaml"))
    fun, point, bounds, outputs, problem = build_batch(cfg, InProcessEvaluator(resolve_disciplines(cfg)))
    point.update(motor_kw=80.0, gear_ratio=8.0, battery_kwh=24.0)
    s = sensitivities(fun, point, wrt=list(problem.names), order=2, bounds=bounds)
    fig = write_heatmap(str(tmp_path / "s.png"), s, outputs, cfg)
    title = fig._suptitle.get_text()
    assert "motor_kw=80" in title and "cycle nedc" in title
    bars, *mats = [a for a in fig.axes if a.get_label() != "<colorbar>"]
    assert bars.get_title().startswith("first order")
    assert len(bars.patches) == len(outputs) * len(problem.names)
    images = [a.images[0] for a in mats]
    assert len(images) == len(outputs)
    lims = {im.get_clim() for im in images}
    assert len(lims) == 1, "one colour scale for every matrix"
    lo, hi = lims.pop()
    assert lo == -hi and hi > 0
    # motor speed is linear in the gear ratio and independent of the rest: every entry is noise
    speed = mats[outputs.index("motor_speed_max_rad_s")]
    assert np.ma.getmaskarray(speed.images[0].get_array()).all()
    assert {t.get_text() for t in speed.texts} == {"≤ err"}
    # the strongest cell (acceleration, motor-motor) is dark and labelled in white
    acc = mats[outputs.index("accel_time_0_100_s")]
    strongest = max(acc.texts, key=lambda t: abs(float(t.get_text().split()[0])) if t.get_text()[0] != "≤" else 0)
    assert strongest.get_color() == "white"
    assert (tmp_path / "s.png").stat().st_size > 1000


def test_the_title_names_the_design_point_when_only_a_parameter_is_analysed(tmp_path):
    cfg = load_config(str(ROOT / "config/leaf_nedc.yaml"))
    fun, point, bounds, outputs, problem = build_batch(cfg, InProcessEvaluator(resolve_disciplines(cfg)))
    param = next(k for k in point if k not in problem.names)
    point.update(motor_kw=70.0)
    s = sensitivities(fun, point, wrt=[param], order=1, bounds=bounds)
    fig = write_heatmap(str(tmp_path / "p.png"), s, outputs, cfg, {k: point[k] for k in problem.names})
    title = fig._suptitle.get_text()
    assert "motor_kw=70, gear_ratio=8, battery_kwh=24" in title and f"{param}=" in title


def test_a_problem_without_a_vehicle_names_no_energy_model(tmp_path):
    """Ishigami's figure was titled '..., flat model': the config's default energy model, of no discipline."""
    from bev_mdo.cli.sensitivity import _context_title

    class S:
        names, point = ("x1",), {"x1": 0.0}
    assert _context_title(S, {"energy_model": "flat"}) == "at x1=0"
    assert _context_title(S, {"energy_model": "flat", "cycle": {"name": "nedc"}}) == "at x1=0; cycle nedc, flat model"


def test_the_title_names_the_cycle_mix_the_energy_is_computed_on(tmp_path):
    """leaf_epa_combined's energy is the 55/45 UDDS/HWFET mix (the energy's cycle_weights); its cycle, US06,
    only sets the top speed. The figure was titled 'cycle epa_us06'."""
    cfg = load_config(str(ROOT / "config/leaf_epa_combined.yaml"))
    fun, point, bounds, outputs, problem = build_batch(cfg, InProcessEvaluator(resolve_disciplines(cfg)))
    s = sensitivities(fun, point, wrt=list(problem.names), order=1, bounds=bounds)
    title = write_heatmap(str(tmp_path / "m.png"), s, outputs, cfg)._suptitle.get_text()
    assert "; cycle mix 55 % epa_udds + 45 % epa_hwfet, quasi_static model" in title and "us06" not in title


def test_the_cycle_a_result_is_named_by():
    from bev_mdo.cli import energy_cycle_label

    us06 = {"cycle": {"name": "epa_us06"}}
    assert energy_cycle_label(us06) == "cycle epa_us06"  # the default disciplines: the energy on the config's cycle
    assert energy_cycle_label({**us06, "disciplines": ["vehicle_mass", "energy"]}) == "cycle epa_us06"
    own = {**us06, "disciplines": [{"name": "energy", "options": {"cycle": "/data/runs/trace.csv"}}]}
    assert energy_cycle_label(own) == "cycle trace.csv"  # the energy's option cycle, a CSV by its file name
    assert energy_cycle_label({}) == ""


def test_every_second_order_cell_is_greyed_by_one_noise_rule(tmp_path):
    """A cross term of 0 computed as -5.17e-11 with a Richardson error of 1.29e-11 (steps h and 2h agreed to
    the last bit) was coloured and labelled NC beside greyed neighbours of 0. The error estimate is now at
    least the rounding of the stencil's values, and every such cell is greyed '≤ err'."""
    def fun(X):  # separable: every cross term is 0, its finite difference rounding noise
        sep = 1e3 + 0.5 * np.exp(X[:, 0] / 7) + 3 * np.log(X[:, 1]) + 0.2 * X[:, 2] ** 3 + np.sqrt(X[:, 3])
        return {"big": 1e6 * sep, "lin": 2.0 * X[:, 0] + 5.0 * X[:, 1] - X[:, 2] + 0.1 * X[:, 3] + 17.0}

    off = ~np.eye(4, dtype=bool)
    for pt in ([3.0, 2.0, 1.5, 9.0], [10.0, 0.3, 4.0, 1.1], [0.7, 5.0, 2.2, 30.0]):
        s = sensitivities(fun, dict(zip("abcd", pt)), order=2)
        fig = write_heatmap(str(tmp_path / "n.png"), s, ["big", "lin"])
        for k, ax in zip(("big", "lin"), [a for a in fig.axes if a.images]):
            assert (np.abs(s.second[k]) <= s.second_error[k])[off].all(), (pt, k)
            mask = np.ma.getmaskarray(ax.images[0].get_array())
            assert mask[off].all(), (pt, k)
            texts = {(round(t.get_position()[1]), round(t.get_position()[0])): t.get_text() for t in ax.texts}
            assert all(texts[(i, j)] == "≤ err" for i in range(4) for j in range(4) if i != j), (pt, k, texts)
