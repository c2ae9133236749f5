"""What the built-in disciplines share: the validated vehicle and cycle of a config, the run's
topology (every entry that sets one must agree; the design variables must exist in it), the
constants a coast-down road load replaces, and :class:`Base` (configured parameters merged with
per-point overrides; no option unless a discipline declares its own ``Options``)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from bev_mdo.mdo.discipline import Discipline
from bev_mdo.models import road_load
from bev_mdo.models import topology as topo_model
from bev_mdo.models.cycles import load_cycle, resample
from bev_mdo.models.params import (ENERGY_MODELS, QUASI_STATIC_SPECS, ROAD_LOAD_UNUSED, fitted_values,  # noqa: F401
                                   validate_cycle, validate_vehicle)  # (ENERGY_MODELS re-exported)

GEARBOX_TWO_SPEED_LOSS = QUASI_STATIC_SPECS["two_speed_efficiency_loss"].default  # the thesis' gearbox (§3.3.2)


def platform_two_speed_loss(section: Mapping[str, Any] | None) -> tuple[float, str] | None:
    """(value, set) where the vehicle section's ``two_speed_efficiency_loss`` is a parameter set's fitted figure,
    not one the section states: a shipped set's, or a file set's (its values are in the resolved section; the
    set's own value marks them; None when the file is gone). The EPA fit's figure stands for the fleet's one
    two-speed platform (docs/validation.md), not a gearbox's own loss: the energy charges it (energy is what
    was fitted), the 0-100 km/h time takes the thesis' gearbox loss instead."""
    v = section if isinstance(section, Mapping) else {}
    src = v.get("parameter_set_source") if isinstance(v.get("parameter_set_source"), Mapping) else {}
    name = src.get("file") or v.get("parameter_set")
    try:
        fitted = fitted_values(name).get("two_speed_efficiency_loss") if isinstance(name, str) else None
    except ValueError:
        return None
    stated = v.get("two_speed_efficiency_loss")
    if fitted is None or (stated is not None and not (src and stated == fitted)):
        return None
    return float(fitted), str(src.get("name") or name)


def platform_loss_note(section: Mapping[str, Any] | None) -> str | None:
    """One line where a two-speed design's gear efficiency loss is a fitted set's platform figure
    (:func:`platform_two_speed_loss`): its value, what it stands for, how to set a gearbox's own."""
    found = platform_two_speed_loss(section)
    return found and (
        f"gear_count 2: two_speed_efficiency_loss {found[0]:.3f} is parameter set {found[1]}'s fitted figure for "
        "the fleet's one two-speed platform (Porsche Taycan / Audi e-tron GT: all it uses beyond the fleet), not "
        f"a gearbox's own loss (about 0.01-0.02): the energy charges it, the 0-100 km/h time takes "
        f"{GEARBOX_TWO_SPEED_LOSS:g}; for a gearbox study set vehicle.two_speed_efficiency_loss (the thesis: "
        f"{GEARBOX_TWO_SPEED_LOSS:g}, §3.3.2)")


def vehicle_of(config: Mapping[str, Any]) -> dict[str, float]:
    return validate_vehicle(config.get("vehicle"))


def resampled_cycle(config: Mapping[str, Any], name: str | None = None):
    """The config's cycle on its grid; another cycle (``name``: a cycle name or CSV) on the same grid."""
    c = validate_cycle(config.get("cycle") if name is None else {**(config.get("cycle") or {}), "name": name})
    return resample(load_cycle(c["name"], config.get("cycle_traces")), c["dt_s"], c["interpolation"], c["smoothing"])


TOPOLOGY_DISCIPLINES = ("vehicle_mass", "energy", "acceleration", "cost", "cycle_range", "motor_speed")


def run_topology(config: Mapping[str, Any], options: Mapping[str, Any]) -> topo_model.Topology:
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


def topology_inputs(t: topo_model.Topology) -> tuple[str, ...]:
    out = ["motor_kw"] + (["gear_ratio"] if t.geared else [])
    if t.two_axles:
        out += ["motor_rear_kw"] + (["gear_ratio_rear"] if t.geared else [])
    return tuple(out)


def overridable(v: Mapping[str, float], names) -> list[str]:
    """``names`` and the coast-down road load's constants (models/road_load.py), less the constants a
    road load leaves unused (the air density too): no model reads those then, so they are not overridable per
    point (a sensitivity to them was 0, a sweep over them gave identical rows)."""
    replaced = ROAD_LOAD_UNUSED if road_load.uses_road_load(v) else ()
    return [k for k in [*names, *(k for k in v if k.startswith("road_load_"))] if k not in replaced]


# the unit of every variable a built-in discipline reads or writes (mdo/units.py)
UNITS = {"motor_kw": "kW", "motor_rear_kw": "kW", "battery_kwh": "kWh", "gear_ratio": "1", "gear_ratio_rear": "1",
         "vehicle_mass_kg": "kg", "energy_wh_per_km": "Wh/km", "energy_wall_wh_per_km": "Wh/km", "range_km": "km",
         "accel_time_0_100_s": "s", "motor_speed_max_rad_s": "rad/s", "powertrain_cost_usd": "USD",
         "drive_torque_margin_nm": "N*m", "motor_speed_margin_rad_s": "rad/s", "drive_power_margin_kw": "kW",
         "drive_force_margin_n": "N",
         "battery_power_margin_kw": "kW", "battery_soc_margin": "1",
         "battery_current_margin": "1"}


class Base(Discipline):
    """Holds the configured parameter values and merges per-point overrides."""

    units = UNITS

    @dataclass(frozen=True)
    class Options:  # no option unless a discipline declares its own
        pass

    def __init__(self, parameters: Mapping[str, float]):
        self.parameters = dict(parameters)

    def _params(self, inputs: Mapping[str, np.ndarray]) -> dict:
        # a per-point road load is checked by the models (road_load.checked), as every other parameter
        return {k: (np.asarray(inputs[k], float) if k in inputs else v) for k, v in self.parameters.items()}


def flag(discipline: str, key: str, value: Any) -> bool:
    if not isinstance(value, bool):
        raise ValueError(f"{discipline} option {key} must be true or false, got {value!r}")
    return value
