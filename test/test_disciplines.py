import copy
from pathlib import Path

import numpy as np
import pytest
import yaml

from bev_mdo.disciplines import BUILTIN, BatterySizing, Energy, default_disciplines
from bev_mdo.mdo.discipline import run_discipline
from bev_mdo.mdo.user_class import read_options
from bev_mdo.models.acceleration import NOT_REACHED_S, accel_time_0_100_s
from bev_mdo.models.cycles import nedc, resample
from bev_mdo.models.flat import energy_wh_per_km

ROOT = Path(__file__).resolve().parents[1]


def load(name):
    return yaml.safe_load((ROOT / "config" / name).read_text())


def _build(cls, config, options):
    """A built-in discipline from a config and its options as written (checked as load_config does)."""
    return cls.from_config(config, read_options(cls, options, f"{cls.name}.options"))


def chain(config, x):
    x = dict(x)
    for d in default_disciplines(config):
        assert set(d.outputs).isdisjoint(d.inputs)
        res = run_discipline(d, x)
        x.update(res.outputs)
    return x


def test_nominal_design_leaf_nedc():
    cfg = load("leaf_nedc.yaml")
    x = chain(cfg, {"motor_kw": np.array([80.0]), "gear_ratio": np.array([8.0]), "battery_kwh": np.array([24.0])})
    assert x["vehicle_mass_kg"][0] == pytest.approx(1590.0)
    assert x["range_km"][0] == pytest.approx(24000.0 / x["energy_wh_per_km"][0])
    assert x["motor_speed_max_rad_s"][0] == pytest.approx(8 * (120 / 3.6) / 0.316)
    e = energy_wh_per_km(resample(nedc()), cfg["vehicle"], np.array([1590.0]), np.array([8.0]))
    assert x["energy_wh_per_km"][0] == pytest.approx(e[0])
    assert x["accel_time_0_100_s"][0] == pytest.approx(accel_time_0_100_s(np.array([80.0]), np.array([8.0]), np.array([1590.0]),
                                                                          cfg["vehicle"])[0])


def test_table75_literal_wheel_radius_breaks_motor_speed_limit():
    # Table 7-5's 0.15 m wheel radius (no shipped config uses it, docs/validation.md)
    cfg = load("leaf_nedc.yaml")
    cfg["vehicle"]["wheel_radius_m"] = 0.15
    x = chain(cfg, {"motor_kw": np.array([80.0]), "gear_ratio": np.array([8.0]), "battery_kwh": np.array([24.0])})
    assert x["motor_speed_max_rad_s"][0] > 1000
    # 100 km/h is beyond the 10 500 rpm limit at 8:1: the continuation value, not a time
    assert np.isfinite(x["accel_time_0_100_s"][0]) and x["accel_time_0_100_s"][0] >= NOT_REACHED_S


@pytest.mark.parametrize("topology, design", [
    ("SM-SA", {"motor_kw": 80.0, "gear_ratio": 13.0}),
    ("DM-DA", {"motor_kw": 40.0, "gear_ratio": 7.9, "motor_rear_kw": 40.0, "gear_ratio_rear": 13.0})])
def test_a_design_that_cannot_reach_100_km_h_is_infeasible_not_failed_for_every_optimiser(topology, design):
    """A gear over-speeding its motor before 100 km/h (the rear one under DM-DA) has no 0-100 km/h time;
    the discipline gives the continuation value, so the point is evaluated (not failed): a gradient optimiser
    gets a finite objective and a finite violated time constraint, and NSGA-II an infeasible point."""
    from bev_mdo.config import RunConfig
    from bev_mdo.mdo.driver import build_formulation
    from bev_mdo.mdo.evaluator import InProcessEvaluator
    from bev_mdo.mdo.formulations import FAIL_OBJECTIVE
    from bev_mdo.studies.topologies import config_for_topology

    raw = config_for_topology(load("topologies_artemis.yaml"), topology)
    dvs = raw["problem"]["design_variables"]
    dvs["gear_ratio_rear" if topology == "DM-DA" else "gear_ratio"]["upper"] = 14.0
    raw["problem"]["constraints"]["accel_time_0_100_s"] = {"upper": 9000.0}  # a limit no real design misses
    cfg = RunConfig.load(raw)
    form = build_formulation(cfg.settings, InProcessEvaluator(cfg.disciplines), "mdf")
    X = np.array([[{**design, "battery_kwh": 24.0}[n] for n in form.problem.names]])
    f, g, _ = form.evaluate_batch(X)
    ok, error = form.status(X[0])
    assert ok and not error and np.isfinite(f[0]) and f[0] != FAIL_OBJECTIVE and np.all(np.isfinite(g))
    row = form.problem.constraint_labels.index(next(x for x in form.problem.constraint_labels
                                                    if x.startswith("accel_time_0_100_s <=")))
    assert g[0, row] > 0.1  # violated by over a thousand seconds: the limit must be below NOT_REACHED_S
    assert form.analyse(X).ok[0]  # what mdo.pareto's NSGA-II problem reads: a point, infeasible by g


def test_parameter_override_per_point():
    d = _build(Energy, load("leaf_nedc.yaml"), {})
    assert "drag_area_m2" in d.parameters and "regen_fraction" in d.parameters
    out = d.compute({"vehicle_mass_kg": np.array([1590.0, 1590.0]), "gear_ratio": np.array([8.0, 8.0]),
                     "drag_area_m2": np.array([0.6412, 0.8])})["energy_wh_per_km"]
    assert out[1] > out[0]


def test_battery_sizing_meets_target():
    cfg = load("leaf_nedc.yaml")
    b = _build(BatterySizing, cfg, {})
    kwh = b.compute({"energy_wh_per_km": np.array([100.0])})["battery_kwh"]
    assert kwh[0] == pytest.approx(17.0)  # 170 km x 100 Wh/km


def test_builtin_names_and_shape():
    for name, cls in BUILTIN.items():
        d = _build(cls, {**load("leaf_nedc.yaml"), "problem": {"constraints": {"range_km": {"lower": 170}}}}, {})
        assert d.name == name and d.outputs and d.inputs


def test_unknown_energy_model():
    with pytest.raises(ValueError, match="energy_model"):
        _build(Energy, {**load("leaf_nedc.yaml"), "energy_model": "magic"}, {})


# ---- topologies -------------------------------------------------------------------

def _topo_cfg(topology="SM-SA", dvs=None, **vehicle):
    cfg = load("topologies_artemis.yaml")
    cfg["cycle"] = {"name": "nedc", "dt_s": 1.0}
    cfg["vehicle"].update(vehicle, topology=topology)  # the one topology setting
    cfg["disciplines"] = [{"name": e} if isinstance(e, str) else e for e in cfg["disciplines"]]
    for e in cfg["disciplines"]:
        e.setdefault("options", {})
    if dvs is not None:
        cfg["problem"]["design_variables"] = dvs
    return cfg


def test_topology_settings_must_agree_and_exist():
    from bev_mdo.config import load_config

    cfg = _topo_cfg()
    cfg["disciplines"][0]["options"]["topology"] = "IWM-SA"
    with pytest.raises(ValueError, match="disagree on the topology"):
        load_config(cfg)
    with pytest.raises(ValueError, match="topology must be one of SM-SA, DM-DA, IWM-SA, IWM-DA"):
        load_config(_topo_cfg("HUB-4"))
    with pytest.raises(ValueError, match="'gear_ratio' does not exist in topology IWM-SA"):
        load_config(_topo_cfg("IWM-SA"))  # the SM-SA problem still has gear_ratio


def test_topology_inputs():
    cfg = _topo_cfg("DM-DA", {"motor_kw": {"lower": 20, "upper": 90}, "gear_ratio": {"lower": 4, "upper": 9},
                              "motor_rear_kw": {"lower": 20, "upper": 90}, "gear_ratio_rear": {"lower": 4, "upper": 9},
                              "battery_kwh": {"lower": 18, "upper": 30}})
    d = {n: _build(BUILTIN[n], cfg, e["options"]) for n, e in ((e["name"], e) for e in cfg["disciplines"])}
    assert set(d["energy"].inputs) == {"vehicle_mass_kg", "motor_kw", "gear_ratio", "motor_rear_kw",
                                       "gear_ratio_rear", "battery_kwh"}
    assert set(d["vehicle_mass"].inputs) == {"motor_kw", "battery_kwh", "motor_rear_kw"}
    assert d["cycle_range"].outputs == ("range_nedc_km",)
    x = {"motor_kw": np.array([40.0]), "motor_rear_kw": np.array([40.0]), "battery_kwh": np.array([24.0]),
         "gear_ratio": np.array([7.9]), "gear_ratio_rear": np.array([7.9])}
    m = run_discipline(d["vehicle_mass"], x).outputs["vehicle_mass_kg"]
    assert m[0] - 69.0 == pytest.approx(1572.6)  # Table 4-5
    c = run_discipline(d["cost"], x).outputs["powertrain_cost_usd"]
    assert c[0] == pytest.approx(2 * (16 * 40 + 385) + (11.1 * 4 + 221.1 + 13) * 24 + 680)


def test_dm_da_motor_speed_is_the_faster_of_its_two_geared_motors():
    """motor_speed read gear_ratio only: under DM-DA a rear ratio of 9.4 (the rear motor at ~1,040 rad/s on
    US06) passed a 922 rad/s limit. An in-wheel topology has no ratio to constrain: refused."""
    dvs = {"motor_kw": {"lower": 20, "upper": 90}, "gear_ratio": {"lower": 4, "upper": 9},
           "motor_rear_kw": {"lower": 20, "upper": 90}, "gear_ratio_rear": {"lower": 4, "upper": 12},
           "battery_kwh": {"lower": 18, "upper": 30}}
    cfg = _topo_cfg("DM-DA", dvs)
    d = _build(BUILTIN["motor_speed"], cfg, {})
    assert d.inputs == ("gear_ratio", "gear_ratio_rear")
    x = {"gear_ratio": np.array([6.0, 8.0]), "gear_ratio_rear": np.array([9.4, 7.0])}
    w = run_discipline(d, x).outputs["motor_speed_max_rad_s"]
    v_max = d.max_speed_m_s / 0.316
    np.testing.assert_allclose(w, [9.4 * v_max, 8.0 * v_max])
    part = d.compute_partials(x)
    np.testing.assert_allclose(part[("motor_speed_max_rad_s", "gear_ratio")], [0.0, v_max])
    np.testing.assert_allclose(part[("motor_speed_max_rad_s", "gear_ratio_rear")], [v_max, 0.0])
    # equal ratios (the study's DM-DA start, 7.9 and 7.9): check-partials' central differences see half each;
    # all to the front motor made `bev-mdo check-partials` at the config's start say DISAGREE (exit 1)
    tie = d.compute_partials({"gear_ratio": np.array([7.9]), "gear_ratio_rear": np.array([7.9])})
    np.testing.assert_allclose([tie[("motor_speed_max_rad_s", k)][0] for k in ("gear_ratio", "gear_ratio_rear")],
                               [v_max / 2, v_max / 2])
    assert _build(BUILTIN["motor_speed"], _topo_cfg(), {}).inputs == ("gear_ratio",)  # SM-SA as before
    iwm = _topo_cfg("IWM-SA", {"motor_kw": {"lower": 20, "upper": 90}, "battery_kwh": {"lower": 18, "upper": 30}})
    with pytest.raises(ValueError, match="motor_speed: topology IWM-SA has no gear ratio"):
        _build(BUILTIN["motor_speed"], iwm, {})


def test_two_speed_mass_counted_once():
    from bev_mdo.models import quasi_static as qs

    two = {"gear_count": 2.0, "gear_ratio_2": 4.7, "shift_speed_m_s": 68.1 / 3.6}
    cfg = _topo_cfg(**two)
    d = {e["name"]: _build(BUILTIN[e["name"]], cfg, e["options"]) for e in cfg["disciplines"]}
    x = {"motor_kw": np.array([71.2]), "battery_kwh": np.array([22.3]), "gear_ratio": np.array([13.2])}
    m1 = run_discipline(d["vehicle_mass"], x).outputs["vehicle_mass_kg"]
    cfg1 = _topo_cfg()
    m0 = run_discipline(_build(BUILTIN["vehicle_mass"], cfg1, {}), x).outputs["vehicle_mass_kg"]
    assert m1[0] - m0[0] == pytest.approx(20.0)
    e = run_discipline(d["energy"], {**x, "vehicle_mass_kg": m1}).outputs["energy_wh_per_km"]
    # independent: the quasi-static model adding its own 20 kg to the single-speed mass
    ref = qs.energy_wh_per_km(d["energy"].resampled, {**cfg["vehicle"], **two}, m0, 13.2, 71.2, battery_kwh=22.3)
    assert e[0] == pytest.approx(ref[0], rel=1e-12)
    t = run_discipline(d["acceleration"], {**x, "vehicle_mass_kg": m1}).outputs["accel_time_0_100_s"]
    t_heavier = run_discipline(d["acceleration"], {**x, "vehicle_mass_kg": m1 + 20}).outputs["accel_time_0_100_s"]
    assert np.isfinite(t[0]) and t_heavier[0] > t[0]


def test_quasi_static_energy_uses_battery_kwh():
    from bev_mdo.models import quasi_static as qs

    cfg = _topo_cfg()
    d = _build(BUILTIN["energy"], cfg, {"topology": "SM-SA"})
    assert "battery_kwh" in d.inputs
    x = {"vehicle_mass_kg": np.array([1590.0, 1590.0]), "motor_kw": np.array([80.0, 80.0]),
         "gear_ratio": np.array([7.9, 7.9]), "battery_kwh": np.array([6.0, 30.0])}
    e = run_discipline(d, x).outputs["energy_wh_per_km"]
    ref = qs.energy_wh_per_km(d.resampled, cfg["vehicle"], 1590.0, 7.9, 80.0, battery_kwh=np.array([6.0, 30.0]))
    np.testing.assert_allclose(e, ref, rtol=1e-12)
    assert e[0] > e[1]  # a 6 kWh pack caps regeneration at 2C = 12 kW (§2.3.4 rule 4)


@pytest.mark.parametrize("model", ["flat", "breakdown", "quasi_static", "chain"])
def test_a_road_load_override_per_point_reaches_the_energy_as_it_does_the_acceleration(model):
    """The energy discipline took road_load_* as fixed constants: a per-point override (bev-mdo evaluate
    --set road_load_a_n=500, sweep, sensitivity) moved the acceleration time and left the energy on the
    configured road load (leaf_epa_combined: 124.67 Wh/km with A = 129 N or 500 N)."""
    def config(a_n):
        cfg = load("leaf_nedc.yaml")
        cfg["energy_model"] = model
        for k in ("drag_area_m2", "rolling_resistance"):
            cfg["vehicle"].pop(k, None)
        cfg["vehicle"]["road_load"] = {"a_n": a_n, "b_n_per_m_s": 1.5, "c_n_per_m2_s2": 0.385, "mass_kg": 1590.0}
        return cfg

    design = {"motor_kw": np.array([80.0, 80.0]), "gear_ratio": np.array([8.0, 8.0]),
              "battery_kwh": np.array([24.0, 24.0])}
    energy = next(d for d in default_disciplines(config(129.0)) if d.name == "energy")
    assert "road_load_a_n" in energy.parameters
    got = chain(config(129.0), {**design, "road_load_a_n": np.array([129.0, 500.0])})
    ref = {a: chain(config(a), design) for a in (129.0, 500.0)}
    for i, a in enumerate((129.0, 500.0)):
        for out in ("energy_wh_per_km", "accel_time_0_100_s"):
            assert got[out][i] == pytest.approx(ref[a][out][i], rel=1e-12), (out, a)
    assert got["energy_wh_per_km"][1] > 1.5 * got["energy_wh_per_km"][0]


def test_what_a_coast_down_replaces_is_not_overridable():
    """With a road_load the models read no drag area or rolling coefficient: an override of either
    (bev-mdo evaluate config/leaf_epa_combined.yaml --set ...,drag_area_m2=2) was accepted and changed
    nothing; the config itself refuses giving both."""
    with_rl = {d.name: d for d in default_disciplines(load("leaf_epa_combined.yaml"))}
    thesis = {d.name: d for d in default_disciplines(load("leaf_nedc.yaml"))}
    for name in ("energy", "acceleration"):
        assert {"drag_area_m2", "rolling_resistance"}.isdisjoint(with_rl[name].parameters), name
        assert "road_load_a_n" in with_rl[name].parameters
        assert {"drag_area_m2", "rolling_resistance"} <= set(thesis[name].parameters), name


@pytest.mark.parametrize("model,reads", [("flat", True), ("breakdown", True), ("quasi_static", False), ("chain", False)])
def test_regen_fraction_is_a_parameter_only_of_the_models_that_read_it(model, reads):
    """chain and quasi_static have their own regeneration rules: --set regen_fraction=0 was accepted
    on config/leaf_epa_combined.yaml and left the energy at 124.67 Wh/km."""
    cfg = load("leaf_nedc.yaml")
    cfg["energy_model"] = model
    energy = next(d for d in default_disciplines(cfg) if d.name == "energy")
    assert ("regen_fraction" in energy.parameters) is reads


@pytest.mark.parametrize("name,value,says", [
    ("road_load_a_n", -5.0, "road_load_a_n must be in [0, 5000] N, got -5"),
    ("road_load_mass_kg", 1.0, "road_load_mass_kg must be in [100, 20000] kg, got 1"),
    ("road_load_b_n_per_m_s", -50.0, "road load A + B v + C v^2 must stay > 0 up to 70 m/s"),
])
def test_a_road_load_override_is_checked_as_the_config_is(name, value, says):
    """Per-point road-load values reached the models unchecked: --set road_load_a_n=-5 gave 80.8 Wh/km
    (a negative rolling force) and a changed acceleration time, where the config refuses a_n: -5."""
    cfg = load("leaf_epa_combined.yaml")
    ds = {d.name: d for d in default_disciplines(cfg)}
    x = {"motor_kw": np.array([80.0, 80.0]), "gear_ratio": np.array([8.0, 8.0]),
         "vehicle_mass_kg": np.array([1590.0, 1590.0]), "battery_kwh": np.array([24.0, 24.0]),
         name: np.array([ds["energy"].parameters[name], value])}
    for d in ("energy", "acceleration"):
        res = run_discipline(ds[d], x)
        assert not res.ok[1] and says in res.error, (d, res.error)
    ok = {**x, name: np.array([ds["energy"].parameters[name]] * 2)}
    assert run_discipline(ds["energy"], ok).ok.all()


def test_chain_feasibility_outputs_are_the_tightest_margins_over_the_cycles():
    """energy option feasibility_outputs with the chain: the motor's torque and power margins (what
    chain.simulate's follows is made of), the smallest over every cycle of cycle_weights, so that an
    optimiser can be kept from a motor that cannot follow the cycle."""
    from bev_mdo.config import load_config, resolve_disciplines
    from bev_mdo.models import chain
    from bev_mdo.models.cycles import load_cycle, resample

    raw = yaml.safe_load((Path(__file__).resolve().parents[1] / "config" / "leaf_epa_combined.yaml").read_text())
    raw["energy_model"], raw["vehicle"]["parameter_set"] = "chain", "epa2022_chain"  # the shipped config's on the chain
    cfg = load_config(copy.deepcopy(raw))
    cfg["disciplines"][1]["options"]["feasibility_outputs"] = True
    energy = next(d for d in resolve_disciplines(cfg) if d.name == "energy")
    assert energy.outputs == ("energy_wh_per_km", "energy_wall_wh_per_km", "drive_torque_margin_nm",
                              "drive_power_margin_kw")
    inputs = {"vehicle_mass_kg": np.array([1600.0, 1600.0]), "gear_ratio": np.array([8.0, 8.0]),
              "motor_kw": np.array([80.0, 12.0])}
    out = energy.compute(inputs)
    p = {**energy.extra, **energy.parameters}
    sims = [chain.simulate(resample(load_cycle(c)), p, inputs["vehicle_mass_kg"], inputs["gear_ratio"],
                           inputs["motor_kw"]) for c in ("epa_udds", "epa_hwfet")]
    wall = 0.55 * sims[0].energy_wh_per_km + 0.45 * sims[1].energy_wh_per_km  # the chain's energy is the wall's
    np.testing.assert_allclose(out["energy_wall_wh_per_km"], wall)
    np.testing.assert_allclose(out["energy_wh_per_km"], wall * p["charger_efficiency"])  # the battery's
    np.testing.assert_allclose(out["drive_power_margin_kw"], np.minimum(sims[0].power_margin_kw, sims[1].power_margin_kw))
    np.testing.assert_allclose(out["drive_torque_margin_nm"], np.minimum(sims[0].torque_margin_nm, sims[1].torque_margin_nm))
    assert out["drive_power_margin_kw"][0] > 0 > out["drive_power_margin_kw"][1]  # 12 kW cannot follow
    assert not sims[0].follows[1] or not sims[1].follows[1]
    plain = next(d for d in resolve_disciplines(load_config(raw)) if d.name == "energy")
    for k in ("energy_wh_per_km", "energy_wall_wh_per_km"):
        np.testing.assert_allclose(plain.compute(inputs)[k], out[k], rtol=1e-12)


def test_a_chain_design_that_cannot_follow_the_cycle_is_infeasible_not_failed():
    """1 kW at 0.5:1 on the chain: about 2.2e5 Wh/km (the copper loss of a demand far over the motor's peak
    torque). The range refused any energy over 5000 Wh/km, so the point failed; now its range is a tenth
    of a kilometre, which the range constraint calls infeasible."""
    from bev_mdo.models import range as range_model

    cfg = load("leaf_nedc.yaml")
    cfg["energy_model"] = "chain"
    x = {"motor_kw": np.array([1.0, 80.0]), "gear_ratio": np.array([0.5, 8.0]), "battery_kwh": np.array([24.0, 24.0])}
    discs = {d.name: d for d in default_disciplines(cfg)}
    for name in ("vehicle_mass", "energy", "range"):
        res = run_discipline(discs[name], x)
        assert res.ok.all() and not res.point_errors, res.error
        x.update(res.outputs)
    assert x["energy_wh_per_km"][0] > 5000
    assert x["range_km"][0] == pytest.approx(24000.0 / x["energy_wh_per_km"][0], rel=1e-12) and x["range_km"][0] < 0.2
    for bad in (np.nan, -5.0, np.inf):  # what no physical design gives is still refused
        with pytest.raises(ValueError, match="^energy_wh_per_km must be in"):
            range_model.range_km(24.0, bad)


def test_a_fitted_sets_two_speed_loss_is_charged_to_the_energy_not_to_the_0_100_time():
    """epa2022_quasi_static's two_speed_efficiency_loss (0.084) stands for the fleet's one two-speed platform
    (fitted on its energy), not a gearbox's loss: a two-speed design of config/leaf_epa_combined.yaml took it in
    its 0-100 km/h time too (8.81 s against 7.90 with one gear and the same first gear). The time takes the
    thesis' 0.02, as with that stated; the energy keeps the fitted figure; a stated loss counts in both."""
    base = load("leaf_epa_combined.yaml")
    x = {"motor_kw": np.array([100.0]), "battery_kwh": np.array([30.0]), "gear_ratio": np.array([9.0]),
         "vehicle_mass_kg": np.array([1667.4])}

    def run(**vehicle):
        cfg = {**base, "vehicle": {**base["vehicle"], "gear_count": 2, "gear_ratio_2": 5.0, **vehicle}}
        t = run_discipline(_build(BUILTIN["acceleration"], cfg, {}), x).outputs["accel_time_0_100_s"][0]
        e = run_discipline(_build(BUILTIN["energy"], cfg, {"cycle_weights": {"epa_udds": 0.55, "epa_hwfet": 0.45}}),
                           x).outputs["energy_wh_per_km"][0]
        return t, e

    fitted, gearbox, platform = run(), run(two_speed_efficiency_loss=0.02), run(two_speed_efficiency_loss=0.08415)
    assert fitted[0] == pytest.approx(gearbox[0], rel=1e-12) and platform[0] > fitted[0] + 0.3
    assert fitted[1] == pytest.approx(platform[1], rel=1e-4) and fitted[1] > gearbox[1] * 1.05


def test_a_two_speed_design_on_a_fitted_set_is_told_what_its_loss_stands_for():
    """The same design: a note names the fitted figure and how to set a gearbox's own, for a config that sets
    gear_count 2 (on load, as every command loads it) and for a design that does (evaluate --set, a sweep);
    none where the loss is stated or the design has one gear."""
    import warnings

    from bev_mdo.api.evaluate import design_notes
    from bev_mdo.config import RunConfig
    from bev_mdo.models.cycles import CycleNote

    raw = load("leaf_epa_combined.yaml")

    def notes(**vehicle):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            cfg = RunConfig.load({**raw, "vehicle": {**raw["vehicle"], **vehicle}})
        return [str(w.message) for w in caught if issubclass(w.category, CycleNote) and "fitted" in str(w.message)], cfg

    said, cfg = notes()
    assert said == [] and not any("fitted figure" in n for n in design_notes(cfg, {"gear_count": 1.0}))
    (line,) = [n for n in design_notes(cfg, {"gear_count": 2.0}) if "fitted figure" in n]
    assert "two_speed_efficiency_loss 0.084 is parameter set epa2022_quasi_static's fitted figure" in line
    assert "Taycan" in line and "set vehicle.two_speed_efficiency_loss" in line
    assert not any("fitted figure" in n for n in design_notes(cfg, {"gear_count": 2.0, "two_speed_efficiency_loss": 0.02}))
    said, cfg = notes(gear_count=2, gear_ratio_2=1.0)  # (not above the lowest first gear)
    assert len(said) == 1 and said[0] == line
    assert not any("fitted figure" in n for n in design_notes(cfg, {"gear_count": 2.0}))  # said once, on load
    assert notes(gear_count=2, gear_ratio_2=1.0, two_speed_efficiency_loss=0.02)[0] == []
