"""vehicle.road_load: coast-down A + B v + C v^2 in every energy model and the
acceleration model, equivalent to drag area + rolling resistance when the coefficients match."""
import numpy as np
import pytest

from bev_mdo.config import load_config
from bev_mdo.models import acceleration, breakdown, chain, flat, quasi_static as qs, topology, topology_accel
from bev_mdo.models.cycles import load_cycle, resample
from bev_mdo.models.params import validate_vehicle

M, IG, KW = np.array([1590.0, 1800.0]), np.array([8.0, 9.0]), np.array([80.0, 120.0])
V = validate_vehicle({})
RHO, CDA, CR, G = V["air_density_kg_m3"], V["drag_area_m2"], V["rolling_resistance"], V["gravity_m_s2"]


def _equivalent(mass_scaled: bool):
    """Road-load coefficients equal to the thesis' 1/2 rho CdA v^2 + Cr M g."""
    if mass_scaled:
        return {"road_load_a_n": CR * G * 1590.0, "road_load_b_n_per_m_s": 0.0,
                "road_load_c_n_per_m2_s2": 0.5 * RHO * CDA, "road_load_mass_kg": 1590.0}
    return {"road_load_a_n": CR * G * 1590.0, "road_load_b_n_per_m_s": 0.0,
            "road_load_c_n_per_m2_s2": 0.5 * RHO * CDA, "road_load_mass_kg": 0.0}


@pytest.mark.parametrize("cycle", ["nedc", "epa_udds"])
def test_equivalent_coefficients_give_the_same_energy(cycle):
    r = resample(load_cycle(cycle))
    rl = {**V, **_equivalent(True)}
    for fn in (lambda p: flat.energy_wh_per_km(r, p, M, IG),
               lambda p: breakdown.energy_wh_per_km(r, p, M, IG, KW),
               lambda p: qs.energy_wh_per_km(r, p, M, IG, KW),
               lambda p: topology.energy_wh_per_km(r, p, "DM-DA", M, KW, 24.0, IG, KW, IG),
               lambda p: chain.energy_wh_per_km(r, p, M, IG, KW)):
        a, b = fn(V), fn(rl)
        if fn is not None and np.allclose(a, b, rtol=1e-9):
            continue
        # quasi-static/topology apply rolling resistance at standstill too (thesis); the road load does not
        np.testing.assert_allclose(b, a, rtol=2e-3)
    # the flat model is exact: rolling resistance acts only while moving in both forms
    np.testing.assert_allclose(flat.energy_wh_per_km(r, rl, M, IG), flat.energy_wh_per_km(r, V, M, IG), rtol=1e-12)


def test_acceleration_with_road_load():
    p = {**V, **_equivalent(True)}
    np.testing.assert_allclose(acceleration.accel_time_0_100_s(KW, IG, M, p),
                               acceleration.accel_time_0_100_s(KW, IG, M, V), rtol=1e-12)
    more = {**p, "road_load_c_n_per_m2_s2": 0.8}
    assert np.all(acceleration.accel_time_0_100_s(KW, IG, M, more) > acceleration.accel_time_0_100_s(KW, IG, M, p))


def test_fixed_a_does_not_scale_with_mass():
    r = resample(load_cycle("nedc"))
    fixed, scaled = {**V, **_equivalent(False)}, {**V, **_equivalent(True)}
    e_f = flat.energy_wh_per_km(r, fixed, M, IG)
    e_s = flat.energy_wh_per_km(r, scaled, M, IG)
    assert e_f[0] == pytest.approx(e_s[0], rel=1e-12) and e_f[1] < e_s[1]


def test_vehicle_section_validation():
    v = validate_vehicle({"road_load": {"a_n": 150, "b_n_per_m_s": -1.9, "c_n_per_m2_s2": 0.44}})
    assert v["road_load_a_n"] == 150 and v["road_load_b_n_per_m_s"] == -1.9 and v["road_load_mass_kg"] == 0
    for bad, match in [({"a_n": 1, "b_n_per_m_s": 0}, "missing"),
                       ({"a_n": 1, "b_n_per_m_s": 0, "c_n_per_m2_s2": 0.4, "d": 1}, "unknown key"),
                       ({"a_n": -5, "b_n_per_m_s": 0, "c_n_per_m2_s2": 0.4}, r"road_load.a_n must be in"),
                       ({"a_n": 10, "b_n_per_m_s": -20, "c_n_per_m2_s2": 0.1}, "must stay > 0"),
                       ("fast", "must be a mapping")]:
        with pytest.raises(ValueError, match=match):
            validate_vehicle({"road_load": bad})
    with pytest.raises(ValueError, match="road_load replaces"):
        validate_vehicle({"drag_area_m2": 0.6, "road_load": {"a_n": 1, "b_n_per_m_s": 0, "c_n_per_m2_s2": 0.4}})


def test_config_with_road_load_runs_through_the_disciplines(tmp_path):
    from pathlib import Path

    import yaml

    from bev_mdo.config import resolve_disciplines

    root = Path(__file__).resolve().parents[2]
    raw = yaml.safe_load((root / "config" / "leaf_nedc.yaml").read_text())
    for k in ("drag_area_m2", "rolling_resistance"):
        raw["vehicle"].pop(k)
    raw["vehicle"]["road_load"] = {"a_n": CR * G * 1590.0, "b_n_per_m_s": 0.0, "c_n_per_m2_s2": 0.5 * RHO * CDA,
                                   "mass_kg": 1590.0}
    cfg = load_config(raw)
    discs = {d.name: d for d in resolve_disciplines(cfg)}
    x = {"vehicle_mass_kg": np.array([1590.0]), "gear_ratio": np.array([8.0]), "motor_kw": np.array([80.0])}
    r = resample(load_cycle("nedc"))
    assert discs["energy"].compute(x)["energy_wh_per_km"][0] == pytest.approx(
        flat.energy_wh_per_km(r, V, x["vehicle_mass_kg"], x["gear_ratio"])[0], rel=1e-12)
    assert discs["acceleration"].compute({**x, "battery_kwh": np.array([24.0])})["accel_time_0_100_s"][0] == pytest.approx(
        acceleration.accel_time_0_100_s(x["motor_kw"], x["gear_ratio"], x["vehicle_mass_kg"], V)[0], rel=1e-12)


def test_resolved_flat_form_validates_to_the_same_values():
    """A discipline node receives the resolved vehicle (road_load_* keys); it must validate to the same."""
    v = validate_vehicle({"road_load": {"a_n": 150, "b_n_per_m_s": -1.9, "c_n_per_m2_s2": 0.44}})
    again = validate_vehicle({k: x for k, x in v.items()})
    assert again == v
    v2 = validate_vehicle({"road_load": {"a_n": 150, "b_n_per_m_s": 1, "c_n_per_m2_s2": 0.44, "mass_kg": 1800}})
    assert validate_vehicle(dict(v2)) == v2


@pytest.mark.parametrize("cycle", ["nedc", "wltc_class3"])
def test_flat_moments_equal_direct_sum_with_road_load_on_linear_traces(cycle):
    r = resample(load_cycle(cycle))
    p = {**V, "road_load_a_n": 140.0, "road_load_b_n_per_m_s": -1.5, "road_load_c_n_per_m2_s2": 0.45,
         "road_load_mass_kg": 1600.0}
    m, ig = np.linspace(1200, 2600, 7), np.linspace(4, 11, 7)
    np.testing.assert_allclose(flat.energy_wh_per_km(r, p, m, ig), flat.energy_wh_per_km_direct(r, p, m, ig),
                               rtol=1e-12)


def test_topology_acceleration_with_road_load():
    p = {**V, **_equivalent(True)}
    a = topology_accel.accel_time_s("DM-DA", M, KW, IG, KW, IG, V)
    b = topology_accel.accel_time_s("DM-DA", M, KW, IG, KW, IG, p)
    np.testing.assert_allclose(b, a, rtol=1e-12)
    more = {**p, "road_load_c_n_per_m2_s2": 0.8}
    assert np.all(topology_accel.accel_time_s("DM-DA", M, KW, IG, KW, IG, more) > b)


NEDC = resample(load_cycle("nedc"), 1.0)
MODEL_CALLS = {
    "quasi_static": lambda p: qs.simulate(NEDC, p, 1500.0, 8.0, 80.0),
    "quasi_static reference": lambda p: qs.simulate(NEDC, p, 1500.0, 8.0, 80.0, reference=True),
    "IWM-DA": lambda p: topology.simulate(NEDC, p, "IWM-DA", 1500.0, 40.0, 24.0, motor_rear_kw=40.0),
    "flat": lambda p: flat.energy_wh_per_km(NEDC, p, 1500.0, 8.0),
    "chain": lambda p: chain.energy_wh_per_km(NEDC, p, 1500.0, 8.0, 80.0),
    "acceleration": lambda p: acceleration.accel_time_0_100_s(80.0, 8.0, 1500.0, p),
    "breakdown": lambda p: breakdown.energy_breakdown(NEDC, p, 1500.0),
}


@pytest.mark.parametrize("model", MODEL_CALLS)
@pytest.mark.parametrize("bad, said", [
    ({"road_load_a_n": np.nan}, r"road_load_a_n must be in \[0, 5000\] N, got nan"),  # the compiled loops crashed
    ({"road_load_c_n_per_m2_s2": np.inf}, "road_load_c_n_per_m2_s2 must be in .* got inf"),  # 2170 Wh/km
    ({"road_load_a_n": -500.0}, "road_load_a_n must be in .* got -500"),  # -1.6 Wh/km, chain -82
    ({"road_load_a_n": [150.0, 20.0], "road_load_b_n_per_m_s": -10.0}, "must stay > 0 up to 70 m/s; it is -42.5 N"),
    ({"road_load_mass_kg": -5.0}, "road_load_mass_kg must be in"),  # taken as "A fixed"
])
def test_a_road_load_is_checked_by_every_model_called_directly(model, bad, said):
    """Only the config path checked the coast-down: called directly, a NaN A crashed the process
    (segmentation fault in the compiled loops) and a negative one gave a negative energy."""
    p = {"road_load_a_n": 150.0, "road_load_b_n_per_m_s": 0.3, "road_load_c_n_per_m2_s2": 0.4, **bad}
    with pytest.raises(ValueError, match=said):
        MODEL_CALLS[model](p)
    good = {"road_load_a_n": 150.0, "road_load_b_n_per_m_s": 0.3, "road_load_c_n_per_m2_s2": 0.4, "road_load_mass_kg": 1500.0}
    assert np.all(np.isfinite(getattr(MODEL_CALLS[model](good), "energy_wh_per_km", 1.0)))


def test_the_smallest_road_load_is_exact():
    """A + B v + C v^2 at its vertex -B / 2C (it was read off a 701-speed grid), at 0 or at 70 m/s."""
    from bev_mdo.models.params import road_load_minimum

    low, at = road_load_minimum([100.0, 100.0, 100.0], [-4.0, 1.0, -1.0], [0.04, 0.4, 0.0])
    np.testing.assert_allclose(low, [0.0, 100.0, 30.0], atol=1e-12)
    np.testing.assert_allclose(at, [50.0, 0.0, 70.0])


def test_no_measured_car_of_the_shipped_fleet_reads_as_a_unit_mix_up():
    """The plausibility note of a config's coast-down must not fire on real cars: none of the 62 training rows."""
    import csv
    from pathlib import Path

    from bev_mdo.models.road_load import implausible_note

    path = Path(__file__).resolve().parents[2] / "bev_mdo" / "data" / "epa_2022_bev" / "train.csv"
    rows = list(csv.DictReader(path.open(encoding="utf-8")))
    assert len(rows) == 62
    for r in rows:
        flat = {"road_load_a_n": float(r["road_load_a_n"]), "road_load_b_n_per_m_s": float(r["road_load_b_n_per_m_s"]),
                "road_load_c_n_per_m2_s2": float(r["road_load_c_n_per_m2_s2"]), "road_load_mass_kg": float(r["test_mass_kg"])}
        assert implausible_note(flat) is None, (r["make"], r["model"])
        lbf = {**flat, "road_load_a_n": flat["road_load_a_n"] / 4.448, "road_load_c_n_per_m2_s2":
               flat["road_load_c_n_per_m2_s2"] / 22.3}  # as EPA publishes them: lbf, lbf/mph^2
        assert implausible_note(lbf) is not None, (r["make"], r["model"])
