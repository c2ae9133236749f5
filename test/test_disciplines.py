from pathlib import Path

import numpy as np
import pytest
import yaml

from bev_mdo.disciplines import BUILTIN, BatterySizing, Energy, default_disciplines
from bev_mdo.mdo.discipline import run_discipline
from bev_mdo.models.acceleration import accel_time_0_100_s
from bev_mdo.models.cycles import nedc, resample
from bev_mdo.models.flat import energy_wh_per_km

ROOT = Path(__file__).resolve().parents[1]


def load(name):
    return yaml.safe_load((ROOT / "config" / name).read_text())


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


def test_table75_breaks_motor_speed_limit():
    x = chain(load("leaf_table75.yaml"), {"motor_kw": np.array([80.0]), "gear_ratio": np.array([8.0]),
                                          "battery_kwh": np.array([24.0])})
    assert x["motor_speed_max_rad_s"][0] > 1000


def test_parameter_override_per_point():
    d = Energy.from_config(load("leaf_nedc.yaml"), {})
    assert "drag_area_m2" in d.parameters and "regen_fraction" in d.parameters
    out = d.compute({"vehicle_mass_kg": np.array([1590.0, 1590.0]), "gear_ratio": np.array([8.0, 8.0]),
                     "drag_area_m2": np.array([0.6412, 0.8])})["energy_wh_per_km"]
    assert out[1] > out[0]


def test_battery_sizing_meets_target():
    cfg = load("leaf_nedc.yaml")
    b = BatterySizing.from_config(cfg, {})
    kwh = b.compute({"energy_wh_per_km": np.array([100.0])})["battery_kwh"]
    assert kwh[0] == pytest.approx(17.0)  # 170 km x 100 Wh/km


def test_builtin_names_and_shape():
    for name, cls in BUILTIN.items():
        d = cls.from_config({**load("leaf_nedc.yaml"), "problem": {"constraints": {"range_km": {"lower": 170}}}}, {})
        assert d.name == name and d.outputs and d.inputs


def test_unknown_energy_model():
    with pytest.raises(ValueError, match="energy_model"):
        Energy.from_config({**load("leaf_nedc.yaml"), "energy_model": "magic"}, {})
