"""The wall-to-wheel chain, the fleet file and the shipped calibration."""
import numpy as np
import pytest

from bev_mdo.models import chain, fleet as fl
from bev_mdo.models.cycles import load_cycle, resample
from bev_mdo.models.params import load_parameter_set, validate_vehicle

R = resample(load_cycle("epa_udds"))
BASE = {"road_load_a_n": 150.0, "road_load_b_n_per_m_s": 1.0, "road_load_c_n_per_m2_s2": 0.4,
        "motor_torque_per_kw": 2.0, "aux_power_w": 300.0, "charger_efficiency": 0.9}


def e(**kw):
    p = {**BASE, **{k: v for k, v in kw.items() if k not in ("m", "ig", "kw")}}
    return chain.simulate(R, p, kw.get("m", 2000.0), kw.get("ig", 9.0), kw.get("kw", 150.0))


def test_stages_move_the_energy_the_right_way():
    ref = e().energy_wh_per_km[0]
    assert e(charger_efficiency=0.8).energy_wh_per_km[0] == pytest.approx(ref * 0.9 / 0.8, rel=1e-12)
    assert e(aux_power_w=600.0).energy_wh_per_km[0] > ref
    assert e(regen_axle_share=0.5).energy_wh_per_km[0] > ref
    assert e(regen_min_speed_m_s=10.0).energy_wh_per_km[0] > ref
    assert e(gear_efficiency=0.9).energy_wh_per_km[0] > ref
    assert e(battery_discharge_resistance_ohm=0.5).energy_wh_per_km[0] > ref
    assert e(motor_loss_copper_fraction=0.2).energy_wh_per_km[0] > ref
    assert e(motor_loss_standby_fraction=0.01).energy_wh_per_km[0] > ref
    assert e(rotating_mass_fraction=0.1).energy_wh_per_km[0] > ref


def test_technology_terms_are_off_for_a_single_speed_synchronous_car_and_cost_energy_otherwise():
    ref = e().energy_wh_per_km[0]
    # a single-speed car with synchronous machines: the technology losses do not apply
    assert e(two_speed_efficiency_loss=0.2, induction_loss_fraction=0.2).energy_wh_per_km[0] == ref
    two = e(gear_count=2.0, two_speed_efficiency_loss=0.02).energy_wh_per_km[0]
    assert two == pytest.approx(e(gear_efficiency=0.95).energy_wh_per_km[0], rel=1e-12)  # 0.97 - 0.02
    half = e(induction_machine_share=0.5, induction_loss_fraction=0.02).energy_wh_per_km[0]
    full = e(induction_machine_share=1.0, induction_loss_fraction=0.02).energy_wh_per_km[0]
    assert ref < half < full
    with pytest.raises(ValueError, match="gear_count must be 1 or 2"):
        e(gear_count=1.5)


def test_a_second_driven_axle_draws_its_drag_while_the_car_moves():
    """All-wheel drive (driven_axles 2) adds second_axle_drag_w at the battery for every moving second,
    braking included (the regeneration rule compares two powers that both carry it), nothing at a
    standstill; one driven axle ignores it. Without pack resistance the cost is exact."""
    lossless = {"battery_discharge_resistance_ohm": 0.0, "battery_charge_resistance_ohm": 0.0}
    one = e(**lossless, second_axle_drag_w=200.0).energy_wh_per_km[0]
    assert one == e(**lossless).energy_wh_per_km[0]
    two = e(**lossless, driven_axles=2.0, second_axle_drag_w=200.0).energy_wh_per_km[0]
    t, v = np.asarray(R.time_s, float), np.asarray(R.speed_m_s, float)
    moving_h = np.diff(t)[(v[1:] + v[:-1]) > 0].sum() / 3600.0
    km = np.sum(np.diff(t) * (v[1:] + v[:-1]) / 2.0) / 1e3
    assert two - one == pytest.approx(200.0 * moving_h / km / 0.9, rel=1e-9)
    with pytest.raises(ValueError, match="driven_axles must be 1 or 2"):
        e(driven_axles=1.5)


def test_the_fleet_files_technology_columns_as_chain_inputs():
    f = fl.read_fleet()
    t = f.technology_params()
    assert np.array_equal(t["driven_axles"], f.driven_axles) and set(t["driven_axles"]) == {1.0, 2.0}
    by_model = {(mk, md): (g, s) for mk, md, g, s in zip(f.make, f.model, t["gear_count"], t["induction_machine_share"])}
    assert by_model[("Tesla", "Model 3 Long Range AWD")] == (1.0, 0.5)   # induction front, PMSM rear
    assert {s for (mk, md), (g, s) in by_model.items() if mk == "Porsche"} == {0.0}
    assert {g for (mk, md), (g, s) in by_model.items() if mk == "Porsche"} == {2.0}
    assert sum(s == 1.0 for s in t["induction_machine_share"]) == 6   # the e-tron SUVs: all induction
    wound = [(mk, s) for mk, s in zip(f.make, t["wound_rotor_machine_share"]) if s]  # i4 and iX: EESM
    assert {mk for mk, _ in wound} == {"BMW"} and len(wound) == 10 and {s for _, s in wound} == {1.0}


def test_aux_power_is_exact_per_km():
    d = e(aux_power_w=1300.0).energy_wh_per_km[0] - e().energy_wh_per_km[0]
    c = load_cycle("epa_udds")
    assert d == pytest.approx(1000.0 * c.duration_s / 3600.0 / (c.distance_m / 1e3) / 0.9, rel=1e-9)


def test_loss_model_is_homogeneous_in_rated_power():
    """Two motors of P/2 sharing the torque lose what one motor of P loses: doubling the rated power
    halves the copper loss at a given torque and doubles the standby loss."""
    cu = {"motor_loss_copper_fraction": 0.1, "motor_loss_standby_fraction": 0.0}
    sb = {"motor_loss_copper_fraction": 0.0, "motor_loss_standby_fraction": 0.004}
    zero = {"motor_loss_copper_fraction": 0.0, "motor_loss_standby_fraction": 0.0}
    base = {k: e(kw=k, **zero).battery_wh_per_km[0] for k in (100.0, 200.0)}
    cu_loss = {k: e(kw=k, **cu).battery_wh_per_km[0] - base[k] for k in (100.0, 200.0)}
    sb_loss = {k: e(kw=k, **sb).battery_wh_per_km[0] - base[k] for k in (100.0, 200.0)}
    assert cu_loss[200.0] == pytest.approx(cu_loss[100.0] / 2, rel=0.05)  # regen share shifts slightly
    assert sb_loss[200.0] == pytest.approx(sb_loss[100.0] * 2, rel=0.05)


def test_a_motor_too_small_is_reported():
    r = e(kw=np.array([150.0, 12.0]), m=np.array([2000.0, 2000.0]), ig=np.array([9.0, 9.0]))
    assert r.follows.tolist() == [True, False]


def test_parameter_set_is_named_by_a_config_and_overridable():
    ps = load_parameter_set("epa2022_chain")
    v = validate_vehicle({"parameter_set": "epa2022_chain", "aux_power_w": 500.0})
    assert v["charger_efficiency"] == pytest.approx(ps["charger_efficiency"]) and v["aux_power_w"] == 500.0
    with pytest.raises(ValueError, match="parameter_set 'nope' is unknown"):
        validate_vehicle({"parameter_set": "nope"})


def test_a_parameter_set_of_your_own_is_named_by_its_path(tmp_path, monkeypatch):
    """calibrate --write FILE writes a set anywhere; a config could only name the shipped ones
    ('parameter_set must be one of ['epa2022_chain']' for a path), so a user's calibration could not be used."""
    own = tmp_path / "my_fleet.yaml"
    own.write_text("name: my_fleet\nenergy_model: chain\nparameters: {charger_efficiency: 0.9, regen_axle_share: 0.7}\n")
    v = validate_vehicle({"parameter_set": str(own), "regen_axle_share": 0.5})
    assert v["charger_efficiency"] == 0.9 and v["regen_axle_share"] == 0.5
    monkeypatch.chdir(tmp_path)  # relative to the working directory, as a drive-cycle CSV
    assert load_parameter_set("my_fleet.yaml")["charger_efficiency"] == 0.9
    with pytest.raises(ValueError, match="'nope.yaml': no such file"):
        load_parameter_set("nope.yaml")
    (tmp_path / "typo.yml").write_text("energy_model: chain\nparameters: {charger_eficiency: 0.9}\n")
    with pytest.raises(ValueError, match=r"typo.yml: parameters.charger_eficiency: unknown key; did you mean 'charger_efficiency'\?"):
        load_parameter_set("typo.yml")
    (tmp_path / "text.yaml").write_text("energy_model: chain\nparameters: {charger_efficiency: high}\n")
    with pytest.raises(ValueError, match="parameters.charger_efficiency must be a number"):
        load_parameter_set("text.yaml")
    with pytest.raises(ValueError, match="must be one of"):
        load_parameter_set("../epa2022_chain")


def test_shipped_data_is_the_shared_data():
    import hashlib
    from pathlib import Path

    import csv

    shared = Path("/work/shared/data")
    pairs = [(Path(chain.__file__).parent.parent / "data" / "drive_cycles" / f"epa_{c}.csv",
              shared / "drive_cycles" / f"epa_{c}.csv") for c in ("udds", "hwfet", "us06")]
    for ours, theirs in pairs:
        assert ours.is_file()
        if theirs.is_file():
            assert hashlib.sha256(ours.read_bytes()).digest() == hashlib.sha256(theirs.read_bytes()).digest()
    # the fleet file: the shared columns cell for cell, plus the technology columns at the end
    theirs = shared / "epa_2022_bev" / "train.csv"
    with open(fl.DEFAULT_FLEET, newline="") as f:
        ours_rows = list(csv.reader(f))
    assert ours_rows[0][-len(fl.TECHNOLOGY):] == list(fl.TECHNOLOGY)
    if theirs.is_file():
        with open(theirs, newline="") as f:
            theirs_rows = list(csv.reader(f))
        assert [r[:-len(fl.TECHNOLOGY)] for r in ours_rows] == theirs_rows


def test_calibration_reproduces_the_shipped_fit():
    """Refitting on the shipped file gives the shipped values (the fit is deterministic)."""
    from bev_mdo.models import calibrate

    f = fl.read_fleet()
    got = calibrate.fit(f, model="chain")
    ps = load_parameter_set(calibrate.PARAMETER_SET)
    for k, x in zip(got["names"], got["x"]):
        assert x == pytest.approx(ps[k], rel=1e-3, abs=1e-5), k


def test_family_grouping_is_one_rule():
    f = fl.read_fleet()
    fam = f.family()
    assert len(set(fam)) == 15
    assert fam[f.model.index("Mustang Mach-E AWD")] == fam[f.model.index("Mach-E")] == "ford mach-e"
    assert fam[f.model.index("Model Y AWD")] != fam[f.model.index("Model 3 RWD")]
