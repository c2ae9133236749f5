"""Built-in disciplines: thin wrappers binding bev_mdo.models to named batched inputs/outputs.

Each reads ``config["vehicle"]`` (validated by models.params), ``config["cycle"]`` and
``config["energy_model"]``. ``parameters`` maps the model constants a caller may override
per point (by sending an input column of the same name) to their configured values.

Each declares its options once, in a dataclass ``Options`` (mdo/user_class.py ``read_options``: a key
it does not declare is refused when the config is loaded); ``from_config`` gets an instance.

Topology (thesis ch.4, models/topology.py): the option ``topology`` (SM-SA | DM-DA | IWM-SA |
IWM-DA, default SM-SA) of vehicle_mass, energy, acceleration, cost and cycle_range; every
entry that sets it must agree, and the problem's design variables must exist in it
(``gear_ratio`` is not one of IWM-*, ``motor_rear_kw`` not one of *-SA). Two-axle topologies
take ``motor_rear_kw`` (and DM-DA ``gear_ratio_rear``); non-SM-SA needs energy_model
quasi_static. The two-speed gearbox's 20 kg (``two_speed_added_mass_kg``) is added ONCE, by
vehicle_mass; energy and cycle_range pass 0 to the quasi-static model so that mass, energy,
range and acceleration all see the same vehicle mass.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from bev_mdo.disciplines.common import (ENERGY_MODELS, GEARBOX_TWO_SPEED_LOSS, TOPOLOGY_DISCIPLINES, Base, overridable,
                                        platform_two_speed_loss, resampled_cycle, run_topology, topology_inputs,
                                        vehicle_of)
from bev_mdo.disciplines.energy import CycleRange, Energy
from bev_mdo.models import acceleration, cost, motor_speed, range as range_model
from bev_mdo.models import topology as topo_model
from bev_mdo.models import topology_accel
from bev_mdo.models.params import vehicle_choice

__all__ = ["ENERGY_MODELS", "TOPOLOGY_DISCIPLINES", "BUILTIN", "VehicleMass", "Energy", "CycleRange", "Range",
           "Acceleration", "MotorSpeed", "Cost", "BatterySizing", "default_names", "default_disciplines"]


class VehicleMass(Base):
    """motor_kw, battery_kwh (, motor_rear_kw) -> vehicle_mass_kg (eq 7-19 or ch.3 compounding;
    Table 4-2 motor unit of the topology; + 20 kg with a two-speed gearbox, §3.7)."""

    name = "vehicle_mass"
    outputs = ("vehicle_mass_kg",)
    _NAMES = {"ch7": ("glider_kg", "load_kg", "motor_kg_per_kw", "motor_base_kg", "battery_kg_per_kwh"),
              "compounding": ("load_kg", "kerb_reference_kg", "reference_motor_kw", "reference_battery_kwh",
                              "mass_compounding", "motor_kg_per_kw", "motor_base_kg", "battery_kg_per_kwh")}
    _TOPO = {"SM-SA": ("gear_count", "two_speed_added_mass_kg"), "DM-DA": ("dm_da_transmission_kg",),
             "IWM-SA": ("iwm_mass_factor",), "IWM-DA": ("iwm_mass_factor",)}

    @dataclass(frozen=True)
    class Options:
        mass_model: str | None = None  # ch7 | compounding (default: vehicle.mass_model)
        topology: str | None = None    # SM-SA | DM-DA | IWM-SA | IWM-DA (default: the run's)

    def __init__(self, parameters: Mapping[str, float], mass_model: str = "ch7", topology: str = "SM-SA"):
        super().__init__(parameters)
        self.mass_model = mass_model
        self.topology = topo_model.get_topology(topology)
        self.inputs = ("motor_kw", "battery_kwh") + (("motor_rear_kw",) if self.topology.two_axles else ())

    @classmethod
    def from_config(cls, config, options):
        v = vehicle_of(config)
        model = options.mass_model or vehicle_choice(config.get("vehicle"), "mass_model")
        if model not in cls._NAMES:
            raise ValueError(f"vehicle_mass option mass_model must be one of {sorted(cls._NAMES)}, got {model!r}")
        t = run_topology(config, options)
        names = cls._NAMES[model] + tuple(k for k in cls._TOPO[t.name] if k in v)
        if t.name != "SM-SA":
            names += ("reference_motor_kw",)
        return cls({k: v[k] for k in dict.fromkeys(names)}, model, t.name)

    def compute(self, inputs):
        m = topo_model.vehicle_mass_kg(self.topology, inputs["motor_kw"], inputs["battery_kwh"],
                                       self._params(inputs), self.mass_model, inputs.get("motor_rear_kw"))
        return {"vehicle_mass_kg": m}

    @property
    def provides_partials(self) -> bool:  # analytic for the single-motor topology (eq 7-19 / ch.3)
        return self.topology.name == "SM-SA"

    def compute_partials(self, inputs):
        """Eq 7-19 is linear: dM/dP = motor kg/kW, dM/dE = battery kg/kWh (x the compounding
        factor with the ch.3 rule)."""
        p = self._params(inputs)
        n = len(inputs["motor_kw"])
        factor = 1.0 if self.mass_model == "ch7" else p["mass_compounding"]
        return {("vehicle_mass_kg", "motor_kw"): np.broadcast_to(factor * p["motor_kg_per_kw"], (n,)),
                ("vehicle_mass_kg", "battery_kwh"): np.broadcast_to(factor * p["battery_kg_per_kwh"], (n,))}


class Range(Base):
    """battery_kwh, energy_wh_per_km (from the battery) -> range_km (eq 7-28)."""

    name = "range"
    inputs = ("battery_kwh", "energy_wh_per_km")
    outputs = ("range_km",)

    @classmethod
    def from_config(cls, config, options):
        return cls({"battery_usable_fraction": vehicle_of(config)["battery_usable_fraction"]})

    def compute(self, inputs):
        p = self._params(inputs)
        return {"range_km": range_model.range_km(inputs["battery_kwh"], inputs["energy_wh_per_km"],
                                                 p["battery_usable_fraction"])}

    def compute_partials(self, inputs):
        """Eq 7-28, R = f E_b 1000 / e: dR/dE_b = f 1000 / e, dR/de = -R / e."""
        f = self._params(inputs)["battery_usable_fraction"]
        e, b = inputs["energy_wh_per_km"], inputs["battery_kwh"]
        return {("range_km", "battery_kwh"): f * 1000.0 / e + 0.0 * b,
                ("range_km", "energy_wh_per_km"): -f * b * 1000.0 / (e * e)}


class Acceleration(Base):
    """motor_kw, gear_ratio, battery_kwh, vehicle_mass_kg (, rear motor) -> accel_time_0_100_s (eqs 7-30 /
    2-26 / 4-5) with every motor of the topology, within the tyres' grip and the pack's power at its
    discharge limit (§3.5.3: 5C; ``battery_to_shaft_efficiency`` 0: no battery limit); SM-SA two-speed
    follows the eq 2-6 shift rule, its gearbox losing ``two_speed_efficiency_loss`` (a fitted set's figure, which
    stands for a platform's energy, is replaced by the thesis' gearbox loss: common.platform_two_speed_loss). A
    design that cannot reach 100 km/h gets the continuation value (models/acceleration.py: 10 000 s + 100 s per
    km/h of top speed short), infeasible under any upper limit the config accepts, not a failed point."""

    name = "acceleration"
    outputs = ("accel_time_0_100_s",)
    # from NOT_REACHED_S up the time is the continuation of a design that cannot reach 100 km/h: an upper
    # limit must lie below it (config/disciplines.py) so that such a design is infeasible whatever the limit
    upper_limit_below = {"accel_time_0_100_s": (acceleration.NOT_REACHED_S, "from there up the value marks a "
                                                "design that cannot reach 100 km/h")}
    _TOPO = {"SM-SA": ("gear_count", "gear_ratio_2", "shift_speed_m_s", "two_speed_efficiency_loss"),
             "DM-DA": (), "IWM-SA": ("iwm_speed_scale",), "IWM-DA": ("iwm_speed_scale",)}

    @dataclass(frozen=True)
    class Options:
        topology: str | None = None

    def __init__(self, parameters, topology: str = "SM-SA"):
        super().__init__(parameters)
        self.topology = topo_model.get_topology(topology)
        self.inputs = (*topology_inputs(self.topology), "battery_kwh", "vehicle_mass_kg")

    @classmethod
    def from_config(cls, config, options):
        v = vehicle_of(config)
        t = run_topology(config, options)
        names = acceleration.ACCEL_PARAMS + acceleration.BATTERY_LIMIT_PARAMS + tuple(k for k in cls._TOPO[t.name]
                                                                                     if k in v)
        p = {k: v[k] for k in overridable(v, names)}
        if "two_speed_efficiency_loss" in p and platform_two_speed_loss(config.get("vehicle")):
            p["two_speed_efficiency_loss"] = GEARBOX_TWO_SPEED_LOSS  # a fitted energy figure, not the box's traction loss
        return cls(p, t.name)

    def compute(self, inputs):
        p = self._params(inputs)
        if self.topology.name == "SM-SA" and np.all(np.asarray(p.get("gear_count", 1.0)) == 1.0):
            t = acceleration.accel_time_0_100_s(inputs["motor_kw"], inputs["gear_ratio"], inputs["vehicle_mass_kg"],
                                                {k: p[k] for k in p if k in acceleration.ACCEL_PARAMS
                                                 or k in acceleration.BATTERY_LIMIT_PARAMS
                                                 or k.startswith("road_load_")}, continuation=True,
                                                battery_kwh=inputs["battery_kwh"])
        else:
            t = topology_accel.accel_time_s(self.topology, inputs["vehicle_mass_kg"], inputs["motor_kw"],
                                            inputs.get("gear_ratio"), inputs.get("motor_rear_kw"),
                                            inputs.get("gear_ratio_rear"), p, continuation=True,
                                            battery_kwh=inputs["battery_kwh"])
        return {"accel_time_0_100_s": t}

    def battery_limit(self, values) -> dict | None:
        """The pack's limit on the 0-100 km/h time at one design (``values``: its inputs and outputs), as evaluate's
        JSON gives it: the pack's shaft power at its discharge limit and the motors' rated power together, kW; the
        time without the pack's limit, s; whether the pack limits the time (below base speed a motor does not use
        its rated power (a short gear), and a pack under it need not bind); ``note``, the line that says so where
        it does. None without a battery limit (``battery_to_shaft_efficiency`` 0) or inputs."""
        if any(k not in values for k in (*self.inputs, "accel_time_0_100_s")) or not np.isfinite(
                values["accel_time_0_100_s"]):  # (a failed point: no time to compare)
            return None
        shaft_w = acceleration.battery_shaft_power_w(float(values["battery_kwh"]), self._params(values))
        if not np.isfinite(shaft_w):
            return None
        rated_kw = self.topology.front_motors * float(values["motor_kw"]) \
            + self.topology.rear_motors * float(values.get("motor_rear_kw", 0.0))
        free = {k: np.atleast_1d(float(values[k])) for k in (*self.inputs, *self.parameters) if k in values}
        t_free = self.compute({**free, "battery_to_shaft_efficiency": np.zeros(1)})["accel_time_0_100_s"]
        t, t_free, shaft_kw = float(values["accel_time_0_100_s"]), float(np.ravel(t_free)[0]), float(shaft_w) / 1e3
        limits = bool(t > t_free * (1 + 1e-9))
        return {"pack_shaft_power_kw": shaft_kw, "motors_rated_power_kw": rated_kw, "time_without_limit_s": t_free,
                "limits": limits, "note": limits and f"the pack limits the 0-100 km/h time: {shaft_kw:.1f} kW at the "
                f"shaft, below the motors' rated {rated_kw:.1f} kW ({t:.3g} s; {t_free:.3g} s without the pack's limit)"}

    def notes(self, values) -> list[str]:
        """What the time means at a design (``values``: inputs and outputs) that cannot reach 100 km/h (the
        continuation value); that the pack's power limits it: ``battery_limit``."""
        return [n for n in [acceleration.not_reached_note(values.get("accel_time_0_100_s") or 0.0)] if n]


class MotorSpeed(Base):
    """gear_ratio (DM-DA: and gear_ratio_rear) -> motor_speed_max_rad_s over the configured cycle (eq 7-29):
    the faster of the topology's geared motors. An in-wheel topology has no gear: refused."""

    name = "motor_speed"
    outputs = ("motor_speed_max_rad_s",)

    @dataclass(frozen=True)
    class Options:
        topology: str | None = None

    def __init__(self, parameters, max_speed_m_s: float, topology: str = "SM-SA"):
        super().__init__(parameters)
        self.max_speed_m_s = float(max_speed_m_s)
        t = topo_model.get_topology(topology)
        if not t.geared:
            raise ValueError(f"motor_speed: topology {t.name} has no gear ratio (its motors turn with the wheels); "
                             "constrain energy's motor_speed_margin_rad_s (options: {feasibility_outputs: true})")
        self.inputs = ("gear_ratio", "gear_ratio_rear") if t.two_axles else ("gear_ratio",)

    @classmethod
    def from_config(cls, config, options):
        v = vehicle_of(config)
        keys = ("wheel_radius_m", "gear_count", "shift_strategy", "gear_ratio_2", "shift_speed_m_s")
        return cls({k: v[k] for k in keys}, float(np.max(resampled_cycle(config).speed_m_s)),
                   run_topology(config, options).name)

    def _ratio(self, inputs) -> np.ndarray:
        ig = np.asarray(inputs["gear_ratio"], float)
        return np.maximum(ig, inputs["gear_ratio_rear"]) if "gear_ratio_rear" in self.inputs else ig

    @staticmethod
    def _shifts(p) -> np.ndarray:
        """Per point: a two-speed gearbox shifting by speed, its second gear above the shift speed (eq 2-6).
        Choosing the gear per step (shift_strategy 1) may use either: the first gear's speed bounds it."""
        return (np.asarray(p["gear_count"]) == 2.0) & (np.asarray(p["shift_strategy"]) == 0.0)

    def compute(self, inputs):
        p = self._params(inputs)
        ratio, v, rw = self._ratio(inputs), self.max_speed_m_s, p["wheel_radius_m"]
        two = motor_speed.motor_speed_max_rad_s(ratio, v, rw, (p["gear_ratio_2"], p["shift_speed_m_s"]))
        return {"motor_speed_max_rad_s": np.where(self._shifts(p), two, motor_speed.motor_speed_max_rad_s(ratio, v, rw))}

    def compute_partials(self, inputs):
        """Eq 7-29, w = i_g v_max / r_w: dw/di_g = v_max / r_w, for the motor with the larger ratio (two
        speeds: min(v_max, v_shift) / r_w where the first gear sets it, else 0)."""
        p = self._params(inputs)
        rw = p["wheel_radius_m"]
        slope = np.broadcast_to(self.max_speed_m_s / rw, (len(inputs["gear_ratio"]),))
        if "gear_ratio_rear" not in self.inputs:  # two speeds: SM-SA only
            ig = np.asarray(inputs["gear_ratio"], float)
            v, shift = self.max_speed_m_s, p["shift_speed_m_s"]
            first = ig * np.minimum(v, shift) >= np.where(v >= shift, p["gear_ratio_2"] * v, 0.0)
            slope = np.where(self._shifts(p), np.where(first, np.minimum(v, shift) / rw, 0.0), slope)
            return {("motor_speed_max_rad_s", "gear_ratio"): slope}
        ig, ig_rear = np.asarray(inputs["gear_ratio"], float), np.asarray(inputs["gear_ratio_rear"], float)
        # equal ratios (the topology study's start point) are a kink: half to each, as central differences see it
        front = np.where(ig > ig_rear, 1.0, np.where(ig < ig_rear, 0.0, 0.5))
        return {("motor_speed_max_rad_s", "gear_ratio"): front * slope,
                ("motor_speed_max_rad_s", "gear_ratio_rear"): (1.0 - front) * slope}


class Cost(Base):
    """motor_kw, battery_kwh (, motor_rear_kw) -> powertrain_cost_usd (eqs 2-21..2-24, Table 4-3, eq 4-4).
    Option ``gearbox_cost_usd`` (default 0: eq 4-4 has no gearbox term)."""

    name = "cost"
    outputs = ("powertrain_cost_usd",)

    @dataclass(frozen=True)
    class Options:
        topology: str | None = None
        gearbox_cost_usd: float = 0.0  # eq 4-4 has no gearbox term

    def __init__(self, parameters, topology: str = "SM-SA", gearbox_cost_usd: float = 0.0):
        super().__init__(parameters)
        self.topology = topo_model.get_topology(topology)
        if isinstance(gearbox_cost_usd, bool) or not isinstance(gearbox_cost_usd, (int, float)):
            raise ValueError(f"cost option gearbox_cost_usd must be a number, got {gearbox_cost_usd!r}")
        self.gearbox_cost_usd = float(gearbox_cost_usd)
        if not (np.isfinite(self.gearbox_cost_usd) and self.gearbox_cost_usd >= 0):
            raise ValueError(f"cost option gearbox_cost_usd must be >= 0, got {gearbox_cost_usd!r}")
        self.inputs = ("motor_kw", "battery_kwh") + (("motor_rear_kw",) if self.topology.two_axles else ())

    @classmethod
    def from_config(cls, config, options):
        return cls({"power_to_energy_ratio": vehicle_of(config)["power_to_energy_ratio"]},
                   run_topology(config, options).name, options.gearbox_cost_usd)

    def compute(self, inputs):
        p = self._params(inputs)
        if self.topology.name == "SM-SA" and self.gearbox_cost_usd == 0.0:
            c = cost.powertrain_cost_usd(inputs["motor_kw"], inputs["battery_kwh"], p["power_to_energy_ratio"])
        else:
            c = topo_model.powertrain_cost_usd(self.topology, inputs["motor_kw"], inputs["battery_kwh"],
                                               inputs.get("motor_rear_kw"), p["power_to_energy_ratio"],
                                               self.gearbox_cost_usd)
        return {"powertrain_cost_usd": c}

    @property
    def provides_partials(self) -> bool:  # analytic for the single-motor topology
        return self.topology.name == "SM-SA"

    def compute_partials(self, inputs):
        """Eqs 2-21..2-24 are linear: dC/dP = 16 $/kW, dC/dE = 11.1 P/E + 221.1 + 13 $/kWh
        (a gearbox cost is a constant)."""
        pe = self._params(inputs)["power_to_energy_ratio"]
        n = len(inputs["motor_kw"])
        return {("powertrain_cost_usd", "motor_kw"): np.full(n, 16.0),
                ("powertrain_cost_usd", "battery_kwh"): np.broadcast_to(11.1 * np.asarray(pe) + 221.1 + 13.0, (n,))}


class BatterySizing(Base):
    """energy_wh_per_km -> battery_kwh giving exactly the target range (eq 7-28 inverted)."""

    name = "battery_sizing"
    inputs = ("energy_wh_per_km",)
    outputs = ("battery_kwh",)

    @dataclass(frozen=True)
    class Options:
        range_target_km: float | None = None  # default: the problem's range_km lower constraint

    def __init__(self, parameters, range_target_km: float):
        super().__init__(parameters)
        self.range_target_km = float(range_target_km)

    @classmethod
    def from_config(cls, config, options):
        target = options.range_target_km
        if target is None:
            target = ((config.get("problem") or {}).get("constraints") or {}).get("range_km", {}).get("lower")
        if target is None:
            raise ValueError("battery_sizing needs option range_target_km (or a range_km lower constraint)")
        range_model.check_design("range_target_km", target)
        return cls({"battery_usable_fraction": vehicle_of(config)["battery_usable_fraction"]}, float(target))

    def compute(self, inputs):
        p = self._params(inputs)
        return {"battery_kwh": range_model.battery_kwh_for_range(self.range_target_km, inputs["energy_wh_per_km"],
                                                                 p["battery_usable_fraction"])}

    def compute_partials(self, inputs):
        """Eq 7-28 inverted, E_b = R e / (1000 f): dE_b/de = R / (1000 f)."""
        f = self._params(inputs)["battery_usable_fraction"]
        n = len(inputs["energy_wh_per_km"])
        return {("battery_kwh", "energy_wh_per_km"): np.broadcast_to(self.range_target_km / (1000.0 * np.asarray(f)), (n,))}


BUILTIN: dict[str, type] = {
    "vehicle_mass": VehicleMass,
    "energy": Energy,
    "range": Range,
    "acceleration": Acceleration,
    "motor_speed": MotorSpeed,
    "cost": Cost,
    "battery_sizing": BatterySizing,
    "cycle_range": CycleRange,
}


def default_names(config: Mapping[str, Any]) -> list[str]:
    """Names of the default disciplines of a config (without building them)."""
    names = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost"]
    if (config.get("problem") or {}).get("battery_sized_for_range"):
        names.append("battery_sizing")
    return names


def default_disciplines(config: Mapping[str, Any]) -> list:
    """The thesis' Fig 7-17 disciplines plus cost; battery sizing when the problem asks for it."""
    return [BUILTIN[n].from_config(config, BUILTIN[n].Options()) for n in default_names(config)]
