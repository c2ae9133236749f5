"""The chapter-4 derivation of docs/thesis.md ("Chapter 4 against Table 4-5") against the models:
every figure the docs print is recomputed here (bev_mdo/studies/thesis_ch4.py), and the findings
they state (ch.5's assumptions reproduce Table 4-5 within 3 % in the thesis' order; equal split ==
the single-axle sibling at the same mass; the cost offsets) are asserted on the computed values."""
import re
from pathlib import Path

import pytest

from bev_mdo.studies import thesis_ch4 as t4

DOC = (Path(__file__).resolve().parents[2] / "docs" / "thesis.md").read_text(encoding="utf-8")
SECTION = DOC[DOC.index("**Chapter 4 against Table 4-5.**"):DOC.index("**Two-speed gearbox")]
NUM = r"[+\-−]?[\d.]+(?: kWh)?"


def _doc_rows(first_cell: str, n: int) -> dict[str, list[float]]:
    """Table rows of the section whose first cell matches ``first_cell`` -> their first n numbers after it."""
    out = {}
    for line in SECTION.splitlines():
        m = re.match(r"\s*\|\s*" + first_cell + r"\s*\|(.*)", line)
        if m:
            cells = [c.strip() for c in m.group(2).split("|")]
            nums = [float(c.replace("−", "-").removesuffix(" kWh")) for c in cells if re.fullmatch(NUM, c)]
            out[m.group(1)] = nums[:n]
    return out


@pytest.fixture(scope="module")
def gap():
    return {r["key"]: r for r in t4.gap_table()}


@pytest.mark.slow
def test_documented_energy_steps_are_the_computed_ones(gap):
    doc = _doc_rows(r"`(\w+)`", 4)
    assert list(doc) == [k for k, _, _ in t4.STEPS]  # every step documented, in order, none extra
    for key, nums in doc.items():
        assert nums == pytest.approx([gap[key][t] for t in t4.TOPOLOGIES], abs=0.006), key


@pytest.mark.slow
@pytest.mark.parametrize("key,tol", [("ch5_30", 0.015), ("ch5_40", 0.03)])
def test_ch5_assumptions_reproduce_table_4_5_in_its_order(gap, key, tol):
    row = gap[key]
    for t in t4.TOPOLOGIES:
        assert row[t] == pytest.approx(t4.THESIS_ENERGY[t], rel=tol), t
    order = sorted(t4.TOPOLOGIES, key=lambda t: row[t])
    assert order == sorted(t4.TOPOLOGIES, key=t4.THESIS_ENERGY.get) == ["IWM-SA", "IWM-DA", "SM-SA", "DM-DA"]


@pytest.mark.slow
def test_shipped_models_differ_from_table_4_5_as_documented(gap):
    base = gap["baseline"]
    assert base["DM-DA"] < base["SM-SA"]  # the thesis has DM-DA above SM-SA
    for t in t4.TOPOLOGIES:  # ~19-27 % below, and no single ch.2-4 factor but no_regen reaches Table 4-5
        assert base[t] < 0.85 * t4.THESIS_ENERGY[t]
        for key in ("regen_from_0", "soc_100", "battery_loss", "drag_appendix_a", "mass_plus_5", "flat_85"):
            assert gap[key][t] < 0.95 * t4.THESIS_ENERGY[t], (key, t)
    # a power-minimising split is never above the equal split, which is the mass effect only
    assert base["DM-DA"] <= gap["equal_split"]["DM-DA"] and base["IWM-DA"] <= gap["equal_split"]["IWM-DA"]
    assert gap["equal_split"]["DM-DA"] / gap["equal_split"]["SM-SA"] - 1 == pytest.approx(0.011, abs=0.002)
    # the split's saving is the map's free idle machine: charged its no-load loss, DM-DA is above SM-SA again
    idle = gap["idle_loss"]
    assert idle["DM-DA"] / idle["SM-SA"] - 1 == pytest.approx(0.011, abs=0.002) and idle["IWM-DA"] > idle["IWM-SA"]


@pytest.mark.parametrize("topology", ["DM-DA", "IWM-DA"])
def test_equal_split_is_the_single_axle_sibling_at_the_same_mass(topology):
    split, single = t4.equal_split_identity(topology)
    assert split == pytest.approx(single, rel=1e-12) and single > 100.0


@pytest.mark.slow
def test_documented_parts_beside_table_3_2():
    doc = _doc_rows(r"(urban|rural|motorway 130)", 3)
    rows = t4.segment_table()
    assert len(doc) == len(rows) == 3
    for (name, nums), r in zip(doc.items(), rows):
        assert nums == pytest.approx([r["kwh"], r["kwh_ch5_30"], r["thesis_kwh"]], abs=6e-4), name
    # chapter 3's urban part is below the ch5 assumptions, its motorway within 2 %
    assert rows[0]["kwh_ch5_30"] > 1.4 * rows[0]["thesis_kwh"]
    assert rows[2]["kwh_ch5_30"] == pytest.approx(rows[2]["thesis_kwh"], rel=0.02)
    assert t4.table_3_2_combined_kwh_per_100km() == pytest.approx(15.65, abs=0.005)
    assert "15.65 kWh/100 km" in SECTION


@pytest.mark.slow
def test_documented_aux_load_is_computed():
    assert t4.aux_power_to_close_w() / 1e3 == pytest.approx(1.59, abs=0.006)
    assert "1.59 kW" in SECTION


def test_documented_cost_offsets_are_computed():
    doc = _doc_rows(r"(SM-SA|DM-DA|IWM-SA|IWM-DA)", 7)
    rows = t4.cost_table()
    assert list(doc) == list(t4.TOPOLOGIES)
    for r in rows:
        expect = [r["motors_usd"], r["eq_4_4_usd"], r["thesis_usd"], r["offset_usd"], r["implied_pack_usd"],
                  r["implied_pack_kwh"]]
        assert doc[r["topology"]][:6] == pytest.approx(expect, abs=0.06), r["topology"]
    by = {r["topology"]: r for r in rows}
    assert by["SM-SA"]["implied_pack_usd"] == pytest.approx(by["DM-DA"]["implied_pack_usd"], abs=1e-9)
    assert by["SM-SA"]["offset_usd"] == pytest.approx(108.7, abs=1e-9)
    assert by["IWM-SA"]["implied_pack_usd"] > by["SM-SA"]["implied_pack_usd"] + 20.0  # no single rule


def _pct(x: float) -> str:
    return f"{x:+.1f}".replace("-", "−")


@pytest.mark.slow
def test_documented_gaps_to_table_4_5_are_the_computed_ones(gap):
    """The docs said every topology's energy was "≈ 19 %" below Table 4-5; that was SM-SA's alone."""
    row = next(line for line in SECTION.splitlines() if line.startswith("| `baseline` / Table 4-5 |"))
    cells = [c.strip() for c in row.split("|")[3:7]]
    pct = {t: 100 * (gap["baseline"][t] / t4.THESIS_ENERGY[t] - 1) for t in t4.TOPOLOGIES}
    assert cells == [f"{_pct(pct[t])} %" for t in t4.TOPOLOGIES]
    summary = ", ".join(f"{t} {_pct(round(pct[t]))[:-2]} %" for t in t4.TOPOLOGIES)
    assert summary in DOC.replace("\n", " ") and "≈ 19 % below" not in DOC


def test_documented_benchmark_times_beside_table_4_4():
    """The docs said `parameter_set: thesis` gave the thesis' times exactly; only SM-SA's matches."""
    from bev_mdo.models import topology_accel as ta
    from bev_mdo.studies.topologies import BENCHMARK, THESIS_4_5

    text = DOC.replace("\n", " ")
    for t in t4.TOPOLOGIES:
        d = BENCHMARK[t]
        ours = float(ta.accel_time_s(t, t4.benchmark_mass_kg(t), d["motor_kw"], d.get("gear_ratio"), d.get("motor_rear_kw"),
                                     d.get("gear_ratio_rear"), params={**t4.BASE_PARAMS, "tyre_grip_coefficient": 0.0})[0])
        thesis = THESIS_4_5[t][1]
        assert f"| {ours:.2f} / {thesis:g} |" in DOC, t
        if t == "SM-SA":
            assert ours == pytest.approx(thesis, abs=0.05)
        else:
            assert f"{t} {_pct(100 * (ours / thesis - 1))} %" in text, t
    assert "gives the thesis' times exactly" not in DOC
