"""The compiled loops (models/compiled.py) against the numpy reference (``reference=True``): energy,
range and every other output of the quasi-static and topology models on 200 random designs per
topology, including two-speed gearboxes, both gear rules, SOCs where rule 4 acts, small packs at
their current limits and a coast-down road load."""
import numpy as np
import pytest

from bev_mdo.models import compiled, topology as tp
from bev_mdo.models.cycles import load_cycle, resample

N = 200
REL = 1e-12


@pytest.fixture(scope="module")
def cycles():
    return resample(load_cycle("wltc_class3"), 1.0), resample(load_cycle("nedc"), 1.0)


def designs(topology, n, seed):
    t = tp.get_topology(topology)
    rng = np.random.default_rng(seed)
    kw = rng.uniform(15, 160, n)
    kw_r = rng.uniform(15, 160, n) if t.two_axles else None
    ig = rng.uniform(3, 11, n) if t.geared else None
    ig_r = rng.uniform(3, 11, n) if t.geared and t.two_axles else None
    args = (rng.uniform(900, 2600, n), kw, rng.uniform(8, 90, n), ig, kw_r, ig_r)  # mass, motor, battery, ...
    params = {"initial_soc": rng.uniform(0.5, 1.0, n), "gear_efficiency": rng.uniform(0.9, 0.99, n)}
    if t.name == "SM-SA":
        params.update(gear_count=rng.choice([1.0, 2.0], n), shift_strategy=rng.choice([0.0, 1.0], n),
                      gear_ratio_2=rng.uniform(2.5, 6, n), shift_speed_m_s=rng.uniform(8, 25, n))
    if t.name == "DM-DA":
        params["second_axle_drag_w"] = rng.uniform(0, 300, n)
    params.update(excitation_loss_w_per_kw=rng.uniform(0, 3, n), wound_rotor_machine_share=rng.uniform(0, 1, n))
    return params, args


def assert_same(fast, ref):
    for name in ("energy_wh_per_km", "regen_wh_per_km", "soc_end", "motor_speed_max_rad_s", "torque_margin_nm",
                 "soc_min", "battery_power_margin_kw", "battery_current_margin"):
        a, b = getattr(fast, name), getattr(ref, name)
        np.testing.assert_allclose(a, b, rtol=REL, atol=0, err_msg=name)
    for name in ("torque_ok", "speed_ok", "current_ok", "power_ok"):
        np.testing.assert_array_equal(getattr(fast, name), getattr(ref, name), err_msg=name)


@pytest.mark.parametrize("topology", tp.TOPOLOGIES)
def test_energy_and_range_equal_the_reference(topology, cycles):
    wltc, nedc = cycles
    params, args = designs(topology, N, seed=list(tp.TOPOLOGIES).index(topology))
    fast = tp.simulate(wltc, params, topology, *args)
    ref = tp.simulate(wltc, params, topology, *args, reference=True)
    assert_same(fast, ref)
    assert fast.energy_wh_per_km.min() > 0
    # the designs reach the limits the flags report, so the flags are compared on both values
    assert not fast.current_ok.all() or not fast.torque_ok.all()
    rng_fast = tp.range_by_repeated_cycle_km(nedc, params, topology, *args)
    rng_ref = tp.range_by_repeated_cycle_km(nedc, params, topology, *args, reference=True)
    np.testing.assert_allclose(rng_fast, rng_ref, rtol=REL, atol=0)
    assert np.all(np.isfinite(rng_ref)) and rng_ref.min() > 10


@pytest.mark.parametrize("topology", ["SM-SA", "DM-DA"])
def test_coast_down_road_load_and_unreached_range(topology, cycles):
    wltc, nedc = cycles
    params, args = designs(topology, 40, seed=7)
    args = (args[0], args[1], np.linspace(2.0, 40.0, 40), *args[3:])  # packs from 2 kWh (< 3 NEDCs) up
    params.update(road_load_a_n=120.0, road_load_b_n_per_m_s=2.0, road_load_c_n_per_m2_s2=0.4,
                  road_load_mass_kg=1500.0)
    fast, ref = tp.simulate(wltc, params, topology, *args), tp.simulate(wltc, params, topology, *args, reference=True)
    np.testing.assert_array_equal(fast.power_ok, ref.power_ok)
    # also where a 2 kWh pack is asked for more than ocv^2/4R and runs at V_BT = ocv/2 + sqrt(~0) (2-14)
    assert 0 < ref.power_ok.sum() < len(ref.power_ok)
    assert_same(fast, ref)
    _, args = designs(topology, 40, seed=7)  # packs of 8 kWh and more: within ocv^2/4R on the NEDC
    fast = tp.range_by_repeated_cycle_km(nedc, params, topology, *args)
    ref = tp.range_by_repeated_cycle_km(nedc, params, topology, *args, reference=True)
    np.testing.assert_allclose(fast, ref, rtol=REL, atol=0)
    assert np.all(np.isfinite(ref))
    short = tp.range_by_repeated_cycle_km(nedc, params, topology, *args, max_repeats=1)  # never reaches 5 %
    assert np.all(np.isinf(short)) and np.all(np.isinf(
        tp.range_by_repeated_cycle_km(nedc, params, topology, *args, max_repeats=1, reference=True)))


@pytest.mark.parametrize("topology", tp.TOPOLOGIES)
def test_the_corners_of_the_design_limits_equal_the_reference(topology, cycles):
    """Designs from the corners of DESIGN_LIMITS (1-1000 kW, 0.5-50:1, 1-500 kWh, 100-20000 kg, log-uniform
    between): many ask more than their pack can give, where V_BT = ocv/2 + sqrt(~0) (2-14) turns an ulp
    of the motor's efficiency into 1e-11 of energy and 1e-9 of SOC. SM-SA's reference read the map through
    scipy, an ulp away from the compiled lookup: it differed by up to 7e-11 (energy) and 4e-10 (range)."""
    from itertools import product

    from bev_mdo.models.common import DESIGN_LIMITS

    wltc, nedc = cycles
    t = tp.get_topology(topology)
    names = ("motor_kw", "gear_ratio", "battery_kwh", "vehicle_mass_kg")
    # the battery has no upper design limit (a sized battery is a result): its corner stays at 500 kWh
    corners = np.array(list(product(*[(DESIGN_LIMITS[k][0], min(DESIGN_LIMITS[k][1], 500.0)) for k in names])))
    rng = np.random.default_rng(11)
    inside = np.exp(rng.uniform(np.log(corners.min(axis=0)), np.log(corners.max(axis=0)), (48, 4)))
    kw, ig, kwh, m = np.vstack([corners, inside]).T
    args = (m, kw, kwh, ig if t.geared else None, kw[::-1].copy() if t.two_axles else None,
            ig[::-1].copy() if t.geared and t.two_axles else None)
    fast, ref = tp.simulate(nedc, {}, topology, *args), tp.simulate(nedc, {}, topology, *args, reference=True)
    assert not ref.power_ok.all()
    assert np.any(ref.soc_min < 0) and np.any(ref.soc_min > 0.5)  # 1 kWh packs run out
    assert_same(fast, ref)
    rng_fast = tp.range_by_repeated_cycle_km(wltc, {}, topology, *args, max_repeats=20)
    rng_ref = tp.range_by_repeated_cycle_km(wltc, {}, topology, *args, max_repeats=20, reference=True)
    np.testing.assert_allclose(rng_fast, rng_ref, rtol=REL, atol=0)


@pytest.mark.parametrize("grid", ["random", "on cell edges"])
def test_interp_is_numpys(grid):
    rng = np.random.default_rng(3)
    # a random grid, and one like the motor map's torque grid, whose points fall on the table's cell edges
    xp = np.cumsum(rng.uniform(0.01, 2.0, 30)) if grid == "random" else np.array([0.0, 5, 10, 20, 30, 45, 60, 80])
    fp = rng.normal(size=xp.size)
    x = np.concatenate([rng.uniform(xp[0] - 1, xp[-1] + 1, 2000), xp, np.nextafter(xp, np.inf),
                        np.nextafter(xp, -np.inf)])
    tables = compiled.grid_table(xp, fp)
    got = np.array([compiled._interp(v, xp, fp, *tables) for v in x])
    np.testing.assert_array_equal(got, np.interp(x, xp, fp))


def test_without_a_cache_directory_it_compiles_in_memory():
    scope = {}
    exec("def twice(x):\n    return 2.0 * x\n", scope)  # no source file: numba has no cache locator
    assert compiled._jit()(scope["twice"])(3.0) == 6.0


@pytest.mark.parametrize("topology", ["SM-SA", "IWM-DA"])
def test_a_design_does_not_depend_on_its_batch(topology, cycles):
    """The battery steps designs in lanes side by side (range: in the order of their estimated
    range) and the kernels split batches over threads: a design's energy and range are the same, to
    the last bit, alone and in any batch, in any order."""
    wltc, nedc = cycles
    params, args = designs(topology, 37, seed=5)  # 37: two blocks of 16 lanes and a short one
    batch = tp.simulate(wltc, params, topology, *args)
    rng = tp.range_by_repeated_cycle_km(nedc, params, topology, *args)
    back = [a if a is None else a[::-1].copy() for a in args]
    params_back = {k: v[::-1].copy() for k, v in params.items()}
    np.testing.assert_array_equal(tp.simulate(wltc, params_back, topology, *back).energy_wh_per_km[::-1],
                                  batch.energy_wh_per_km)
    np.testing.assert_array_equal(tp.range_by_repeated_cycle_km(nedc, params_back, topology, *back)[::-1], rng)
    for i in (0, 20, 36):
        p = {k: v[i:i + 1] for k, v in params.items()}
        one = [a if a is None else a[i:i + 1] for a in args]
        alone = tp.simulate(wltc, p, topology, *one)
        assert alone.energy_wh_per_km[0] == batch.energy_wh_per_km[i]
        assert alone.soc_end[0] == batch.soc_end[i]
        assert tp.range_by_repeated_cycle_km(nedc, p, topology, *one)[0] == rng[i]
