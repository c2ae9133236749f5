"""Pareto plots for any number of objectives with every topology's benchmark design, the
summary naming exactly the PNGs written, and the negative-torque-margin warning."""
from __future__ import annotations

import re
from pathlib import Path

import yaml

from bev_mdo.cli import main
from bev_mdo.studies.topologies import torque_warnings

ARTEMIS = Path(__file__).resolve().parents[2] / "config" / "topologies_artemis.yaml"


def _cfg(tmp_path):
    raw = yaml.safe_load(ARTEMIS.read_text())
    raw["cycle"] = {"name": "nedc", "dt_s": 2.0}  # fast
    p = tmp_path / "cfg.yaml"
    p.write_text(yaml.safe_dump(raw, sort_keys=False))
    return p


def test_two_objectives_write_one_plot_and_say_so(tmp_path, capsys):
    out = tmp_path / "o"
    rc = main(["pareto", str(_cfg(tmp_path)), "--out", str(out), "--generations", "1", "--pop", "8",
               "--objectives", "energy_wh_per_km,powertrain_cost_usd", "--topology", "SM-SA", "--transport", "inprocess"])
    assert rc == 0
    said = capsys.readouterr().out
    pngs = sorted(p.name for p in out.glob("*.png"))
    assert pngs == ["fig_4_6_energy_cost.png"]
    assert "fig_4_6_energy_cost.png" in said
    # history of a Pareto bag: says what it holds instead of iterations, exit 1
    assert main(["history", str(out / "bag")]) == 1
    err = capsys.readouterr().err
    assert "no iteration records" in err and "Pareto bag" in err and "ParetoFront" in err
    # it named `bev-mdo report` for every generation's front, which report does not show
    assert "(bev-mdo report)" not in err and "not shown by bev-mdo report" in err


def test_three_objectives_every_pair_and_all_benchmarks(tmp_path, capsys):
    from bev_mdo.studies import topologies as par

    out = tmp_path / "o"
    seen = []
    orig = par.plot_pair

    def spy(results, bench, xk, yk, path, cycle=""):
        fig = orig(results, bench, xk, yk, path, cycle)
        seen.append((fig, xk, yk, set(results)))
        return fig

    par.plot_pair = spy
    try:
        rc = main(["pareto", str(_cfg(tmp_path)), "--out", str(out), "--generations", "1", "--pop", "8",
                   "--topology", "IWM-SA", "--transport", "inprocess"])
    finally:
        par.plot_pair = orig
    assert rc == 0
    assert len(seen) == 3 and len(list(out.glob("*.png"))) == 3
    for fig, xk, yk, tops in seen:
        ax = fig.axes[0]
        assert re.search(r"\(.+\)$", ax.get_xlabel()) and re.search(r"\(.+\)$", ax.get_ylabel()), "units on axes"
        labels = [t.get_text() for t in ax.get_legend().get_texts()]
        assert all(any(lab.startswith(f"{t} benchmark (Table 4-4)") for lab in labels) for t in tops)


def test_negative_torque_margin_warns():
    w = torque_warnings({"SM-SA": {"drive_torque_margin_nm": 12.0}, "IWM-SA": {"drive_torque_margin_nm": -35.5}})
    assert len(w) == 1 and "IWM-SA" in w[0] and "-35.5" in w[0]
    assert torque_warnings({"SM-SA": {}}) == []
