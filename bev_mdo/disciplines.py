"""Built-in disciplines: thin wrappers binding bev_mdo.models to named batched inputs/outputs.

Each reads ``config["vehicle"]`` (validated by models.params), ``config["cycle"]`` and
``config["energy_model"]``. ``parameters`` maps the model constants a caller may override
per point (by sending an input column of the same name) to their configured values.

Each declares its options once, in a dataclass ``Options`` (mdo/discipline.py ``read_options``: a key
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

import importlib
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from bev_mdo.mdo.discipline import Discipline
from bev_mdo.models import acceleration, cost, flat, motor_speed, range as range_model
from bev_mdo.models import road_load
from bev_mdo.models import topology as topo_model
from bev_mdo.models.cycles import load_cycle, resample
from bev_mdo.models.params import ROAD_LOAD_REPLACES, validate_cycle, validate_vehicle, vehicle_choice

ENERGY_MODELS = ("flat", "breakdown", "quasi_static", "chain")
_ROAD_KEYS = road_load.FLAT_KEYS


def _vehicle(config: Mapping[str, Any]) -> dict[str, float]:
    return validate_vehicle(config.get("vehicle"))


def _resampled(config: Mapping[str, Any]):
    c = validate_cycle(config.get("cycle"))
    return resample(load_cycle(c["name"], config.get("cycle_traces")), c["dt_s"], c["interpolation"], c["smoothing"])


TOPOLOGY_DISCIPLINES = ("vehicle_mass", "energy", "acceleration", "cost", "cycle_range")


def _topology(config: Mapping[str, Any], options: Mapping[str, Any]) -> topo_model.Topology:
    """The run's topology from the discipline options (or ``vehicle.topology`` if the vehicle
    schema allows it); all entries must agree and the design variables must exist in it."""
    chosen = set()
    for e in config.get("disciplines") or []:
        if isinstance(e, Mapping) and isinstance(e.get("options"), Mapping) and "topology" in e["options"]:
            chosen.add(topo_model.get_topology(e["options"]["topology"]).name)
    vt = (config.get("vehicle") or {}).get("topology")
    if vt is not None:
        chosen.add(topo_model.get_topology(vt).name)
    if len(chosen) > 1:
        raise ValueError(f"disciplines disagree on the topology: {sorted(chosen)}; set one topology for all")
    name = options.topology or (chosen.pop() if chosen else "SM-SA")
    t = topo_model.get_topology(name)
    dvs = ((config.get("problem") or {}).get("design_variables") or {})
    topo_model.check_design_variables(t, list(dvs))
    return t


def _topology_inputs(t: topo_model.Topology, *, gear: bool = True) -> tuple[str, ...]:
    out = ["motor_kw"] + (["gear_ratio"] if t.geared and gear else [])
    if t.two_axles:
        out += ["motor_rear_kw"] + (["gear_ratio_rear"] if t.geared and gear else [])
    return tuple(out)


def _replaced_by_road_load(v: Mapping[str, float]) -> tuple[str, ...]:
    """The constants a coast-down road load replaces (models/road_load.py): not overridable per point
    then, since no model reads them (an override such as --set drag_area_m2=0.7 was accepted and
    changed nothing, where the config refuses giving both)."""
    return ROAD_LOAD_REPLACES if road_load.uses_road_load(v) else ()


class _Base(Discipline):
    """Holds the configured parameter values and merges per-point overrides."""

    @dataclass(frozen=True)
    class Options:  # no option unless a discipline declares its own
        pass

    def __init__(self, parameters: Mapping[str, float]):
        self.parameters = dict(parameters)

    def _params(self, inputs: Mapping[str, np.ndarray]) -> dict:
        out = {k: (np.asarray(inputs[k], float) if k in inputs else v) for k, v in self.parameters.items()}
        if any(k in inputs for k in _ROAD_KEYS if k in self.parameters):
            # per-point road load: the models take it as given (no spec table of theirs has it), so the
            # config's checks are applied here (a negative A gave 80.8 Wh/km instead of an error)
            road_load.check_values(out)
        return out


class VehicleMass(_Base):
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
        v = _vehicle(config)
        model = options.mass_model or vehicle_choice(config.get("vehicle"), "mass_model")
        if model not in cls._NAMES:
            raise ValueError(f"vehicle_mass option mass_model must be one of {sorted(cls._NAMES)}, got {model!r}")
        t = _topology(config, options)
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


class Energy(_Base):
    """vehicle_mass_kg, gear_ratio (, motor_kw, battery_kwh, rear motor) -> energy_wh_per_km on the
    configured cycle (option ``cycle`` overrides it). Option ``feasibility_outputs: true`` adds
    ``drive_torque_margin_nm`` (min over the cycle of envelope minus demand; at the motor for
    SM-SA, at the wheels otherwise) and, with quasi_static, ``motor_speed_margin_rad_s`` (limit minus
    max) or, with chain, ``drive_power_margin_kw`` (rated power minus the largest drive power; over
    every cycle of ``cycle_weights``): constrain them >= 0 so that an optimiser cannot pick a motor
    that does not follow the cycle (the chain's energy of such a design is the energy of the demand)."""

    name = "energy"
    outputs = ("energy_wh_per_km",)

    @dataclass(frozen=True)
    class Options:
        energy_model: str | None = None        # default: the config's energy_model
        cycle: str | None = None               # a cycle name or CSV (default: the config's cycle)
        cycle_weights: Mapping[str, float] | None = None  # {cycle: distance share}, summing to 1
        feasibility_outputs: bool = False      # add the drive torque / speed / power margins
        topology: str | None = None

    def __init__(self, parameters, resampled, energy_model: str = "flat", extra: Mapping[str, float] | None = None,
                 topology: str = "SM-SA", feasibility_outputs: bool = False):
        super().__init__(parameters)
        if energy_model not in ENERGY_MODELS:
            raise ValueError(f"energy_model must be one of {list(ENERGY_MODELS)}, got {energy_model!r}")
        self.energy_model = energy_model
        self.resampled = resampled
        self.extra = dict(extra or {})  # fixed constants passed to the model, not overridable
        self.topology = topo_model.get_topology(topology)
        if self.topology.name != "SM-SA" and energy_model != "quasi_static":
            raise ValueError(f"topology {self.topology.name} needs energy_model quasi_static, got {energy_model!r}")
        if feasibility_outputs and energy_model not in ("quasi_static", "chain"):
            raise ValueError("energy option feasibility_outputs needs energy_model quasi_static or chain")
        self.feasibility_outputs = bool(feasibility_outputs)
        if feasibility_outputs:
            self.outputs = ("energy_wh_per_km", "drive_torque_margin_nm",
                            "motor_speed_margin_rad_s" if energy_model == "quasi_static" else "drive_power_margin_kw")
        if energy_model == "flat":
            self.inputs = ("vehicle_mass_kg", "gear_ratio")
            self._fn = flat.energy_wh_per_km
        elif energy_model == "quasi_static":
            # battery_kwh feeds the OCV+R pack (SOC, 2C/5C limits)
            self.inputs = ("vehicle_mass_kg", *_topology_inputs(self.topology), "battery_kwh")
            self._fn = None
        else:
            self.inputs = ("vehicle_mass_kg", "gear_ratio", "motor_kw")
            self._fn = importlib.import_module(f"bev_mdo.models.{energy_model}").energy_wh_per_km

    @classmethod
    def from_config(cls, config, options):
        v = _vehicle(config)
        model = options.energy_model or config.get("energy_model", "flat")
        if model == "flat":
            names = flat.FLAT_PARAMS
        elif model in ENERGY_MODELS:
            specs = getattr(importlib.import_module(f"bev_mdo.models.{model}"), "PARAM_SPECS", {})
            # regen_fraction only where the model reads it (breakdown's specs): chain and quasi_static have
            # their own regeneration rules, and an override of it changed nothing there
            names = tuple(dict.fromkeys([*flat.FLAT_PARAMS[:4], "gear_efficiency", *specs]))
        else:
            raise ValueError(f"energy_model must be one of {list(ENERGY_MODELS)}, got {model!r}")
        # the two-speed mass is added by vehicle_mass (once), never here
        names = [k for k in names if k in v and k != "two_speed_added_mass_kg"]
        # the coast-down road load is overridable per point, as in acceleration (else --set road_load_a_n=..
        # moved the acceleration time and left the energy on the configured road load)
        names += [k for k in v if k.startswith("road_load_")]
        names = [k for k in names if k not in _replaced_by_road_load(v)]
        extra = {k: x for k, x in v.items() if k not in names}
        if model == "quasi_static":
            extra["two_speed_added_mass_kg"] = 0.0
        disc = cls({k: v[k] for k in names}, _cycle_option(config, options), model, extra,
                   _topology(config, options).name, _flag("energy", "feasibility_outputs", options.feasibility_outputs))
        disc.weighted = _cycle_weights(config, options, model)
        return disc

    def _simulate(self, inputs, p):
        return topo_model.simulate(self.resampled, p, self.topology, inputs["vehicle_mass_kg"], inputs["motor_kw"],
                                   inputs["battery_kwh"], inputs.get("gear_ratio"), inputs.get("motor_rear_kw"),
                                   inputs.get("gear_ratio_rear"))

    def compute(self, inputs):
        p = {**self.extra, **self._params(inputs)}
        if self._fn is None:
            r = self._simulate(inputs, p)
            out = {"energy_wh_per_km": r.energy_wh_per_km}
            if self.feasibility_outputs:
                out["drive_torque_margin_nm"] = np.minimum(r.torque_margin_nm, 1e9)
                out["motor_speed_margin_rad_s"] = (np.broadcast_to(p.get("motor_speed_limit_rpm", 10500.0), (len(r.energy_wh_per_km),))
                                                   * np.pi / 30.0 * (1.0 if self.topology.geared else p.get("iwm_speed_scale", 210 / 1099.56))
                                                   - r.motor_speed_max_rad_s)
            return out
        motor_kw = inputs.get("motor_kw")
        if self.feasibility_outputs:  # chain: energy and the motor's margins, the tightest over the cycles
            from bev_mdo.models import chain

            runs = [(w, chain.simulate(r, p, inputs["vehicle_mass_kg"], inputs["gear_ratio"], motor_kw))
                    for w, r in (getattr(self, "weighted", None) or [(1.0, self.resampled)])]
            return {"energy_wh_per_km": sum(w * c.energy_wh_per_km for w, c in runs),
                    "drive_torque_margin_nm": np.minimum.reduce([c.torque_margin_nm for _, c in runs]),
                    "drive_power_margin_kw": np.minimum.reduce([c.power_margin_kw for _, c in runs])}
        if getattr(self, "weighted", None):  # e.g. EPA combined: 0.55 UDDS + 0.45 HWFET by distance
            e = sum(w * self._fn(r, p, inputs["vehicle_mass_kg"], inputs["gear_ratio"], motor_kw)
                    for w, r in self.weighted)
        else:
            e = self._fn(self.resampled, p, inputs["vehicle_mass_kg"], inputs["gear_ratio"], motor_kw)
        return {"energy_wh_per_km": e}


def _cycle_weights(config, options, model):
    """Energy option ``cycle_weights: {cycle: distance share, ...}`` (shares summing to 1): the energy per km
    is the distance-weighted mean over those cycles, e.g. EPA combined {epa_udds: 0.55, epa_hwfet: 0.45}."""
    cw = options.cycle_weights
    if cw is None:
        return None
    if model == "quasi_static":
        raise ValueError("energy option cycle_weights needs energy_model flat, breakdown or chain")
    if not isinstance(cw, Mapping) or not cw:
        raise ValueError("energy option cycle_weights must map cycle names to distance shares")
    total = 0.0
    out = []
    for name, w in cw.items():
        if isinstance(w, bool) or not isinstance(w, (int, float)) or not 0 < w <= 1:
            raise ValueError(f"energy option cycle_weights.{name} must be a share in (0, 1], got {w!r}")
        total += float(w)
        c = validate_cycle({**(config.get("cycle") or {}), "name": name})
        out.append((float(w), resample(load_cycle(c["name"], config.get("cycle_traces")), c["dt_s"],
                                       c["interpolation"], c["smoothing"])))
    if abs(total - 1.0) > 1e-9:
        raise ValueError(f"energy option cycle_weights must sum to 1, got {total:g}")
    return out


def _cycle_option(config, options):
    """The configured cycle, or the discipline option ``cycle`` (a name or CSV) on the same grid."""
    if options.cycle is None:
        return _resampled(config)
    c = validate_cycle({**(config.get("cycle") or {}), "name": options.cycle})
    return resample(load_cycle(c["name"], config.get("cycle_traces")), c["dt_s"], c["interpolation"], c["smoothing"])


class CycleRange(Energy):
    """Chapter-3 range (§3.5.3): repeat ``cycle`` (option, default nedc) from 100 % to 5 % SOC with
    the quasi-static model of the topology -> ``range_<cycle>_km`` (e.g. range_nedc_km)."""

    name = "cycle_range"

    @dataclass(frozen=True)
    class Options:
        cycle: str = "nedc"  # the cycle repeated (a name or CSV)
        topology: str | None = None

    def __init__(self, parameters, resampled, energy_model="quasi_static", extra=None, topology="SM-SA",
                 feasibility_outputs=False):
        super().__init__(parameters, resampled, "quasi_static", extra, topology, False)
        self.outputs = (f"range_{_slug(resampled.name)}_km",)

    @classmethod
    def from_config(cls, config, options):
        return super().from_config(config, Energy.Options(energy_model="quasi_static", cycle=options.cycle,
                                                          topology=options.topology))

    def compute(self, inputs):
        p = {**self.extra, **self._params(inputs)}
        rng = topo_model.range_by_repeated_cycle_km(
            self.resampled, p, self.topology, inputs["vehicle_mass_kg"], inputs["motor_kw"], inputs["battery_kwh"],
            inputs.get("gear_ratio"), inputs.get("motor_rear_kw"), inputs.get("gear_ratio_rear"))
        return {self.outputs[0]: rng}


def _slug(name: str) -> str:
    import re
    return re.sub(r"[^a-z0-9]+", "_", str(name).lower()).strip("_") or "cycle"


class Range(_Base):
    """battery_kwh, energy_wh_per_km -> range_km (eq 7-28)."""

    name = "range"
    inputs = ("battery_kwh", "energy_wh_per_km")
    outputs = ("range_km",)

    @classmethod
    def from_config(cls, config, options):
        v = _vehicle(config)
        out = {"battery_usable_fraction": v["battery_usable_fraction"]}
        if config.get("energy_model") == "chain":  # wall energy -> battery energy (models/chain.py)
            out["charger_efficiency"] = v["charger_efficiency"]
        return cls(out)

    def compute(self, inputs):
        p = self._params(inputs)
        e = inputs["energy_wh_per_km"] * p.get("charger_efficiency", 1.0)
        return {"range_km": range_model.range_km(inputs["battery_kwh"], e, p["battery_usable_fraction"])}

    def compute_partials(self, inputs):
        """Eq 7-28, R = f E_b 1000 / e: dR/dE_b = f 1000 / e, dR/de = -R / e."""
        f = self._params(inputs)["battery_usable_fraction"]
        e, b = inputs["energy_wh_per_km"], inputs["battery_kwh"]
        return {("range_km", "battery_kwh"): f * 1000.0 / e + 0.0 * b,
                ("range_km", "energy_wh_per_km"): -f * b * 1000.0 / (e * e)}


class Acceleration(_Base):
    """motor_kw, gear_ratio, vehicle_mass_kg (, rear motor) -> accel_time_0_100_s (eqs 7-30 / 2-26 / 4-5)
    with every motor of the topology; SM-SA two-speed follows the eq 2-6 shift rule."""

    name = "acceleration"
    outputs = ("accel_time_0_100_s",)
    _TOPO = {"SM-SA": ("gear_count", "gear_ratio_2", "shift_speed_m_s", "two_speed_efficiency_loss"),
             "DM-DA": (), "IWM-SA": ("iwm_speed_scale",), "IWM-DA": ("iwm_speed_scale",)}

    @dataclass(frozen=True)
    class Options:
        topology: str | None = None

    def __init__(self, parameters, topology: str = "SM-SA"):
        super().__init__(parameters)
        self.topology = topo_model.get_topology(topology)
        self.inputs = (*_topology_inputs(self.topology), "vehicle_mass_kg")

    @classmethod
    def from_config(cls, config, options):
        v = _vehicle(config)
        t = _topology(config, options)
        names = acceleration.ACCEL_PARAMS + tuple(k for k in cls._TOPO[t.name] if k in v)
        names += tuple(k for k in v if k.startswith("road_load_"))  # coast-down road load (models/road_load.py)
        return cls({k: v[k] for k in names if k not in _replaced_by_road_load(v)}, t.name)

    def compute(self, inputs):
        p = self._params(inputs)
        if self.topology.name == "SM-SA" and np.all(np.asarray(p.get("gear_count", 1.0)) == 1.0):
            t = acceleration.accel_time_0_100_s(inputs["motor_kw"], inputs["gear_ratio"], inputs["vehicle_mass_kg"],
                                                {k: p[k] for k in p if k in acceleration.ACCEL_PARAMS
                                                 or k.startswith("road_load_")})
        else:
            t = topo_model.accel_time_s(self.topology, inputs["vehicle_mass_kg"], inputs["motor_kw"],
                                        inputs.get("gear_ratio"), inputs.get("motor_rear_kw"),
                                        inputs.get("gear_ratio_rear"), p)
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

    def compute_partials(self, inputs):
        """Eq 7-29, w = i_g v_max / r_w: dw/di_g = v_max / r_w."""
        rw = self._params(inputs)["wheel_radius_m"]
        n = len(inputs["gear_ratio"])
        return {("motor_speed_max_rad_s", "gear_ratio"): np.broadcast_to(self.max_speed_m_s / rw, (n,))}


class Cost(_Base):
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
        return cls({"power_to_energy_ratio": _vehicle(config)["power_to_energy_ratio"]},
                   _topology(config, options).name, options.gearbox_cost_usd)

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


class BatterySizing(_Base):
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
        v = _vehicle(config)
        params = {"battery_usable_fraction": v["battery_usable_fraction"]}
        if config.get("energy_model") == "chain":  # wall energy -> battery energy (models/chain.py)
            params["charger_efficiency"] = v["charger_efficiency"]
        return cls(params, float(target))

    def compute(self, inputs):
        p = self._params(inputs)
        e = inputs["energy_wh_per_km"] * p.get("charger_efficiency", 1.0)
        return {"battery_kwh": range_model.battery_kwh_for_range(self.range_target_km, e,
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


def _flag(discipline: str, key: str, value: Any) -> bool:
    if not isinstance(value, bool):
        raise ValueError(f"{discipline} option {key} must be true or false, got {value!r}")
    return value
