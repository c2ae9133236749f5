"""Built-in disciplines: thin wrappers binding bev_mdo.models to named batched inputs/outputs.

Each reads ``config["vehicle"]`` (validated by models.params), ``config["cycle"]`` and
``config["energy_model"]``. ``parameters`` maps the model constants a caller may override
per point (by sending an input column of the same name) to their configured values.
"""
from __future__ import annotations

import importlib
from typing import Any, Mapping

import numpy as np

from bev_mdo.mdo.discipline import Discipline
from bev_mdo.models import acceleration, cost, flat, mass, motor_speed, range as range_model
from bev_mdo.models.cycles import load_cycle, resample
from bev_mdo.models.params import validate_cycle, validate_vehicle, vehicle_choice

ENERGY_MODELS = ("flat", "breakdown", "quasi_static")


def _vehicle(config: Mapping[str, Any]) -> dict[str, float]:
    return validate_vehicle(config.get("vehicle"))


def _resampled(config: Mapping[str, Any]):
    c = validate_cycle(config.get("cycle"))
    return resample(load_cycle(c["name"]), c["dt_s"], c["interpolation"], c["smoothing"])


class _Base(Discipline):
    """Holds the configured parameter values and merges per-point overrides."""

    def __init__(self, parameters: Mapping[str, float]):
        self.parameters = dict(parameters)

    def _params(self, inputs: Mapping[str, np.ndarray]) -> dict:
        return {k: (np.asarray(inputs[k], float) if k in inputs else v) for k, v in self.parameters.items()}


class VehicleMass(_Base):
    """motor_kw, battery_kwh -> vehicle_mass_kg (eq 7-19 or ch.3 compounding)."""

    name = "vehicle_mass"
    inputs = ("motor_kw", "battery_kwh")
    outputs = ("vehicle_mass_kg",)
    _NAMES = {"ch7": ("glider_kg", "load_kg", "motor_kg_per_kw", "motor_base_kg", "battery_kg_per_kwh"),
              "compounding": ("load_kg", "kerb_reference_kg", "reference_motor_kw", "reference_battery_kwh",
                              "mass_compounding", "motor_kg_per_kw", "motor_base_kg", "battery_kg_per_kwh")}

    def __init__(self, parameters: Mapping[str, float], mass_model: str = "ch7"):
        super().__init__(parameters)
        self.mass_model = mass_model

    @classmethod
    def from_config(cls, config, options):
        v = _vehicle(config)
        model = options.get("mass_model") or vehicle_choice(config.get("vehicle"), "mass_model")
        return cls({k: v[k] for k in cls._NAMES[model]}, model)

    def compute(self, inputs):
        m = mass.vehicle_mass_kg(inputs["motor_kw"], inputs["battery_kwh"], self._params(inputs), self.mass_model)
        return {"vehicle_mass_kg": m}


class Energy(_Base):
    """vehicle_mass_kg, gear_ratio (, motor_kw) -> energy_wh_per_km on the configured cycle."""

    name = "energy"
    outputs = ("energy_wh_per_km",)

    def __init__(self, parameters, resampled, energy_model: str = "flat", extra: Mapping[str, float] | None = None):
        super().__init__(parameters)
        if energy_model not in ENERGY_MODELS:
            raise ValueError(f"energy_model must be one of {list(ENERGY_MODELS)}, got {energy_model!r}")
        self.energy_model = energy_model
        self.resampled = resampled
        self.extra = dict(extra or {})  # fixed constants passed to the model, not overridable
        if energy_model == "flat":
            self.inputs = ("vehicle_mass_kg", "gear_ratio")
            self._fn = flat.energy_wh_per_km
        else:
            self.inputs = ("vehicle_mass_kg", "gear_ratio", "motor_kw")
            self._fn = importlib.import_module(f"bev_mdo.models.{energy_model}").energy_wh_per_km

    @classmethod
    def from_config(cls, config, options):
        v = _vehicle(config)
        model = options.get("energy_model") or config.get("energy_model", "flat")
        if model == "flat":
            names = flat.FLAT_PARAMS
        elif model in ENERGY_MODELS:
            try:
                specs = getattr(importlib.import_module(f"bev_mdo.models.{model}"), "PARAM_SPECS", {})
            except ImportError as exc:
                raise ValueError(f"energy_model {model!r} is not available: {exc}") from None
            names = tuple(dict.fromkeys([*flat.FLAT_PARAMS[:4], "gear_efficiency", "regen_fraction", *specs]))
        else:
            raise ValueError(f"energy_model must be one of {list(ENERGY_MODELS)}, got {model!r}")
        names = [k for k in names if k in v]
        extra = {k: x for k, x in v.items() if k not in names}
        return cls({k: v[k] for k in names}, _resampled(config), model, extra)

    def compute(self, inputs):
        p = {**self.extra, **self._params(inputs)}
        motor_kw = inputs.get("motor_kw")
        e = self._fn(self.resampled, p, inputs["vehicle_mass_kg"], inputs["gear_ratio"], motor_kw)
        return {"energy_wh_per_km": e}


class Range(_Base):
    """battery_kwh, energy_wh_per_km -> range_km (eq 7-28)."""

    name = "range"
    inputs = ("battery_kwh", "energy_wh_per_km")
    outputs = ("range_km",)

    @classmethod
    def from_config(cls, config, options):
        return cls({"battery_usable_fraction": _vehicle(config)["battery_usable_fraction"]})

    def compute(self, inputs):
        p = self._params(inputs)
        return {"range_km": range_model.range_km(inputs["battery_kwh"], inputs["energy_wh_per_km"],
                                                 p["battery_usable_fraction"])}


class Acceleration(_Base):
    """motor_kw, gear_ratio, vehicle_mass_kg -> accel_time_0_100_s (eqs 7-30 / 2-26)."""

    name = "acceleration"
    inputs = ("motor_kw", "gear_ratio", "vehicle_mass_kg")
    outputs = ("accel_time_0_100_s",)

    @classmethod
    def from_config(cls, config, options):
        v = _vehicle(config)
        return cls({k: v[k] for k in acceleration.ACCEL_PARAMS})

    def compute(self, inputs):
        t = acceleration.accel_time_0_100_s(inputs["motor_kw"], inputs["gear_ratio"], inputs["vehicle_mass_kg"],
                                            self._params(inputs))
        return {"accel_time_0_100_s": t}


class MotorSpeed(_Base):
    """gear_ratio -> motor_speed_max_rad_s over the configured cycle (eq 7-29)."""

    name = "motor_speed"
    inputs = ("gear_ratio",)
    outputs = ("motor_speed_max_rad_s",)

    def __init__(self, parameters, max_speed_m_s: float):
        super().__init__(parameters)
        self.max_speed_m_s = float(max_speed_m_s)

    @classmethod
    def from_config(cls, config, options):
        return cls({"wheel_radius_m": _vehicle(config)["wheel_radius_m"]},
                   float(np.max(_resampled(config).speed_m_s)))

    def compute(self, inputs):
        p = self._params(inputs)
        return {"motor_speed_max_rad_s": motor_speed.motor_speed_max_rad_s(
            inputs["gear_ratio"], self.max_speed_m_s, p["wheel_radius_m"])}


class Cost(_Base):
    """motor_kw, battery_kwh -> powertrain_cost_usd (eqs 2-21..2-24)."""

    name = "cost"
    inputs = ("motor_kw", "battery_kwh")
    outputs = ("powertrain_cost_usd",)

    @classmethod
    def from_config(cls, config, options):
        return cls({"power_to_energy_ratio": _vehicle(config)["power_to_energy_ratio"]})

    def compute(self, inputs):
        p = self._params(inputs)
        return {"powertrain_cost_usd": cost.powertrain_cost_usd(inputs["motor_kw"], inputs["battery_kwh"],
                                                                p["power_to_energy_ratio"])}


class BatterySizing(_Base):
    """energy_wh_per_km -> battery_kwh giving exactly the target range (eq 7-28 inverted)."""

    name = "battery_sizing"
    inputs = ("energy_wh_per_km",)
    outputs = ("battery_kwh",)

    def __init__(self, parameters, range_target_km: float):
        super().__init__(parameters)
        self.range_target_km = float(range_target_km)

    @classmethod
    def from_config(cls, config, options):
        target = options.get("range_target_km")
        if target is None:
            target = ((config.get("problem") or {}).get("constraints") or {}).get("range_km", {}).get("lower")
        if target is None:
            raise ValueError("battery_sizing needs option range_target_km (or a range_km lower constraint)")
        range_model.check_design("range_target_km", target)
        return cls({"battery_usable_fraction": _vehicle(config)["battery_usable_fraction"]}, float(target))

    def compute(self, inputs):
        p = self._params(inputs)
        return {"battery_kwh": range_model.battery_kwh_for_range(self.range_target_km, inputs["energy_wh_per_km"],
                                                                 p["battery_usable_fraction"])}


BUILTIN: dict[str, type] = {
    "vehicle_mass": VehicleMass,
    "energy": Energy,
    "range": Range,
    "acceleration": Acceleration,
    "motor_speed": MotorSpeed,
    "cost": Cost,
    "battery_sizing": BatterySizing,
}


def default_disciplines(config: Mapping[str, Any]) -> list:
    """The thesis' Fig 7-17 disciplines plus cost; battery sizing when the problem asks for it."""
    names = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost"]
    if (config.get("problem") or {}).get("battery_sized_for_range"):
        names.append("battery_sizing")
    return [BUILTIN[n].from_config(config, {}) for n in names]
