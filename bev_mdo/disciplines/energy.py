"""The energy disciplines: ``energy`` (energy per km on the configured cycle, or a distance-weighted
mix of cycles, with optional feasibility margins) and ``cycle_range`` (range by repeating a cycle)."""
from __future__ import annotations

import importlib
import re
import sys
import threading
import time
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from bev_mdo.disciplines.common import (ENERGY_MODELS, Base, flag, overridable, resampled_cycle,
                                        run_topology, topology_inputs, vehicle_of)
from bev_mdo.models import flat
from bev_mdo.models import topology as topo_model
from bev_mdo.models.acceleration import ACCEL_PARAMS
from bev_mdo.models.cycles import DriveCycle, resample
from bev_mdo.models.follow import drive_force_margin_n, steps_not_followed
from bev_mdo.models.params import QUASI_STATIC_SPECS

WALL_MODELS = ("chain", "quasi_static")  # the models that know the charger: energy_wall_wh_per_km
BATTERY_MARGINS = ("battery_power_margin_kw", "battery_soc_margin", "battery_current_margin")  # quasi_static's, with feasibility_outputs
FINAL_SOC = QUASI_STATIC_SPECS["final_soc"].default
FOLLOW_INPUTS = ("vehicle_mass_kg", "gear_ratio", "motor_kw")  # the design's, for models/follow.py


def _in_envelope(name: str) -> bool:
    """A constant of the motor envelope and road load that models/follow.py reads (and the gear count)."""
    return name in ACCEL_PARAMS or name.startswith("road_load_") or name == "gear_count"


class Energy(Base):
    """vehicle_mass_kg, gear_ratio (, motor_kw, battery_kwh, rear motor) -> energy_wh_per_km, the energy
    from the battery per km, on the configured cycle (option ``cycle`` overrides it, option ``cycle_weights``
    mixes cycles by distance); the chain and quasi-static models also give ``energy_wall_wh_per_km``, the energy
    from the wall (what EPA measures: the battery's over ``charger_efficiency``, 1 in the thesis' parameters).
    Option ``feasibility_outputs: true`` adds
    ``drive_torque_margin_nm`` (min over the cycle of envelope minus demand; at the motor for
    SM-SA, at the wheels otherwise) and, with quasi_static, ``motor_speed_margin_rad_s`` (limit minus
    max) or, with chain, ``drive_power_margin_kw`` (rated power minus the largest drive power; over
    every cycle of ``cycle_weights``); with flat, ``drive_force_margin_n`` only (the motor envelope's
    net force minus the step's need, models/follow.py; it then reads motor_kw): constrain them >= 0 so
    that an optimiser cannot pick a motor that does not follow the cycle (the energy of such a design is
    the energy of the demand).
    With quasi_static (every topology) it also adds the battery's: ``battery_power_margin_kw`` (min over
    the cycle of the pack's largest power ocv^2/4R minus the drive demand), ``battery_soc_margin``
    (the lowest SOC over the cycle minus ``final_soc``, a fraction of capacity) and
    ``battery_current_margin`` (min over the cycle of 1 - current / the discharge limit
    ``discharge_c_max`` x capacity), the tightest over the cycles: constrain them >= 0 so that an optimiser cannot pick a pack that does not deliver the cycle
    (the model caps such a pack's power and lets its SOC fall below 0, so its energy per km leaves
    out what it did not deliver)."""

    name = "energy"
    outputs = ("energy_wh_per_km",)

    @dataclass(frozen=True)
    class Options:
        energy_model: str | None = None        # default: the config's energy_model
        cycle: str | None = None               # a cycle name or CSV (default: the config's cycle)
        cycle_weights: Mapping[str, float] | None = None  # {cycle: distance share}, summing to 1
        feasibility_outputs: bool = False      # add the drive torque / speed / power and battery margins
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
        if feasibility_outputs and energy_model == "flat" and {**self.extra, **parameters}.get("gear_count", 1.0) != 1.0:
            raise ValueError("energy option feasibility_outputs with energy_model flat covers a single-speed gearbox")
        self.feasibility_outputs = bool(feasibility_outputs)
        self.outputs = ("energy_wh_per_km",) + (("energy_wall_wh_per_km",) if energy_model in WALL_MODELS else ())
        if feasibility_outputs:
            self.outputs += {"quasi_static": ("drive_torque_margin_nm", "motor_speed_margin_rad_s", *BATTERY_MARGINS),
                             "chain": ("drive_torque_margin_nm", "drive_power_margin_kw"),
                             "flat": ("drive_force_margin_n",)}.get(energy_model, ())
        if energy_model == "flat":  # with feasibility_outputs, the motor's envelope too (models/follow.py)
            self.inputs = ("vehicle_mass_kg", "gear_ratio") + (("motor_kw",) if feasibility_outputs else ())
            self._fn = flat.energy_wh_per_km
        elif energy_model == "quasi_static":
            # battery_kwh feeds the OCV+R pack (SOC, 2C/5C limits)
            self.inputs = ("vehicle_mass_kg", *topology_inputs(self.topology), "battery_kwh")
            self._fn = None
        else:
            self.inputs = ("vehicle_mass_kg", "gear_ratio", "motor_kw")
            self._fn = importlib.import_module(f"bev_mdo.models.{energy_model}").energy_wh_per_km

    @classmethod
    def from_config(cls, config, options):
        v = vehicle_of(config)
        model = options.energy_model or config.get("energy_model", "flat")
        if model == "flat":
            names = flat.FLAT_PARAMS
        elif model in ENERGY_MODELS:
            specs = getattr(importlib.import_module(f"bev_mdo.models.{model}"), "PARAM_SPECS", {})
            # regen_fraction only where the model reads it (breakdown's specs): chain and quasi_static have
            # their own regeneration rules
            names = tuple(dict.fromkeys([*flat.FLAT_PARAMS[:4], "gear_efficiency", *specs]))
        else:
            raise ValueError(f"energy_model must be one of {list(ENERGY_MODELS)}, got {model!r}")
        # the two-speed mass is added by vehicle_mass (once), never here
        names = overridable(v, [k for k in names if k in v and k != "two_speed_added_mass_kg"])
        extra = {k: x for k, x in v.items() if k not in names}
        if model == "quasi_static":
            extra["two_speed_added_mass_kg"] = 0.0
        disc = cls({k: v[k] for k in names}, resampled_cycle(config, options.cycle), model, extra,
                   run_topology(config, options).name, flag("energy", "feasibility_outputs", options.feasibility_outputs))
        disc.weighted = _cycle_weights(config, options, model)
        disc.envelope = {k: x for k, x in v.items() if _in_envelope(k)}
        return disc

    def cycle_steps_short(self, values) -> list | None:
        """[(cycle name, its steps, steps not followed (N,), largest force short N (N,), steps of them over the
        motor's speed limit (N,))] of the designs in
        ``values`` (motor_kw, gear_ratio, vehicle_mass_kg: numbers or (N,) arrays) at full motor envelope
        (models/follow.py); -1 steps not followed where that envelope is not the design's (two speeds); None
        where it is no design's: the check covers single-speed SM-SA."""
        if getattr(self, "envelope", None) is None or self.topology.name != "SM-SA" or any(
                values.get(k) is None for k in FOLLOW_INPUTS):
            return None
        env = self._envelope(values)
        cols = np.broadcast_arrays(*(np.atleast_1d(np.asarray(values[k], float)) for k in FOLLOW_INPUTS),
                                   np.atleast_1d(np.asarray(env.pop("gear_count", 1.0), float)))
        one = np.flatnonzero(cols[-1] == 1.0)
        if not one.size:
            return None
        env = {k: (np.broadcast_to(x, cols[0].shape)[one] if np.ndim(x) else x) for k, x in env.items()}
        out = []
        for _, r in self._cycles():
            count, worst, over = np.full(cols[0].size, -1, np.int64), np.zeros(cols[0].size), np.zeros(cols[0].size)
            count[one], worst[one], over[one] = steps_not_followed(r.time_s, r.speed_m_s, env,
                                                                   *(c[one] for c in cols[:3]))
            out.append((r.name, len(r.time_s) - 1, count, worst, over))
        return out

    def _envelope(self, values) -> dict:
        """The motor envelope's and road load's constants (and gear_count) for the designs of ``values``: the
        vehicle's (set by from_config), a per-point value (--set, an input) winning."""
        return {**getattr(self, "envelope", {}), **{k: x for k, x in values.items() if _in_envelope(k)}}

    def cannot_follow(self, values, rows) -> str | None:
        """One line when the one design in ``values`` cannot follow a cycle of the run (``rows``: its
        ``cycle_steps_short``), else None: its energy per km is that of the cycle's demand, not of a
        powertrain that follows it."""
        for name, steps, count, worst, over in rows:
            if count[0] > 0:
                why = [] if over[0] >= count[0] else [f"falls up to {worst[0] / 1e3:.3g} kN short of the drive force"]
                why += [f"turns over its speed limit at {'all of them' if over[0] >= count[0] else f'{int(over[0])} of them'}"
                        ] if over[0] > 0 else []
                return (f"the design cannot follow the cycle {name} at {int(count[0])} of {steps} steps (its "
                        f"{float(values['motor_kw']):.4g} kW motor at {float(values['gear_ratio']):.4g}:1 "
                        f"{' and '.join(why)})"
                        + ("" if not np.isfinite(values.get("energy_wh_per_km", np.nan)) else  # a failed point has none
                           ": its energy per km is that of the cycle's demand, not of a powertrain that follows it"))
        return None

    def notes(self, values) -> list[str]:
        """The breakdown model's energy at one design (``values``: inputs and outputs) row by row, as Table 5-1
        gives it (kWh/100 km; the battery rows are left out of the total, eq 5-21): what the energy is made of."""
        one = {k: np.atleast_1d(np.asarray(values[k], float)) for k in (*self.inputs, *self.parameters) if k in values}
        if self.energy_model != "breakdown" or not all(k in one and np.isfinite(one[k]).all() for k in self.inputs):
            return []  # (sensitivity's point holds no coupling; a failed design's are NaN: its failure says why)
        from bev_mdo.models.breakdown import energy_breakdown

        p = {**self.extra, **self._params(one)}
        try:  # a design the model refuses failed already, and says why
            runs = [(w, energy_breakdown(r, p, one["vehicle_mass_kg"], one.get("gear_ratio"), one.get("motor_kw")))
                    for w, r in self._cycles()]
        except ValueError:
            return []
        rows = {k: sum(w * float(b[k][0]) for w, b in runs)
                for k in ("aerodynamic", "rolling_resistance", "inertia", "regenerative_recovery", "transmission_loss",
                          "motor_loss", "total", "battery_discharge_loss", "battery_charge_loss")}
        parts = ", ".join(f"{k.replace('_', ' ')} {v:.3f}" for k, v in rows.items())
        w = float(np.ravel(p["battery_loss_weight"])[0])
        battery = f"the total holds the battery rows x battery_loss_weight {w:g}" if w else "the battery rows are not in the total"
        return [f"energy by Table 5-1's rows, kWh/100 km: {parts} ({battery})"]

    def prepare(self) -> None:
        """One-time work before the first call, outside any timeout: the quasi-static model's compiled loops."""
        if self.energy_model == "quasi_static":
            warm_up()

    def _cycles(self):
        """[(distance share, resampled cycle)]: those of option cycle_weights, else the one cycle."""
        return getattr(self, "weighted", None) or [(1.0, self.resampled)]

    def _simulate(self, inputs, p, resampled):
        return topo_model.simulate(resampled, p, self.topology, inputs["vehicle_mass_kg"], inputs["motor_kw"],
                                   inputs["battery_kwh"], inputs.get("gear_ratio"), inputs.get("motor_rear_kw"),
                                   inputs.get("gear_ratio_rear"))

    def compute(self, inputs):
        p = {**self.extra, **self._params(inputs)}
        if self._fn is None:  # quasi_static: the battery's energy (2-16, 2-17), the tightest margins over the cycles
            runs = [(w, self._simulate(inputs, p, r)) for w, r in self._cycles()]
            e = sum(w * r.energy_wh_per_km for w, r in runs)  # one cycle: 0 + 1.0 x, the same bits
            out = {"energy_wh_per_km": e, "energy_wall_wh_per_km": e / p.get("charger_efficiency", 1.0)}
            if self.feasibility_outputs:
                out["drive_torque_margin_nm"] = np.minimum(np.minimum.reduce([r.torque_margin_nm for _, r in runs]), 1e9)
                out["motor_speed_margin_rad_s"] = (np.broadcast_to(p.get("motor_speed_limit_rpm", 10500.0), (len(e),))
                                                   * np.pi / 30.0 * (1.0 if self.topology.geared else p.get("iwm_speed_scale", 210 / 1099.56))
                                                   - np.maximum.reduce([r.motor_speed_max_rad_s for _, r in runs]))
                out.update(battery_margins([r for _, r in runs], p.get("final_soc", FINAL_SOC)))
            return out
        motor_kw = inputs.get("motor_kw")
        if self.feasibility_outputs and self._fn is flat.energy_wh_per_km:  # eq 6-50, 6-51 at full envelope
            env = self._envelope(inputs)
            if np.any(np.asarray(env.pop("gear_count", 1.0)) != 1.0):
                raise ValueError("energy option feasibility_outputs with energy_model flat covers a single-speed gearbox")
            return {"energy_wh_per_km": sum(w * self._fn(r, p, inputs["vehicle_mass_kg"], inputs["gear_ratio"])
                                            for w, r in self._cycles()),
                    "drive_force_margin_n": np.minimum.reduce([drive_force_margin_n(
                        r.time_s, r.speed_m_s, env, inputs["vehicle_mass_kg"], inputs["gear_ratio"], motor_kw)
                        for _, r in self._cycles()])}
        if self.feasibility_outputs:  # chain: energy and the motor's margins, the tightest over the cycles
            from bev_mdo.models import chain

            runs = [(w, chain.simulate(r, p, inputs["vehicle_mass_kg"], inputs["gear_ratio"], motor_kw))
                    for w, r in self._cycles()]
            wall = sum(w * c.energy_wh_per_km for w, c in runs)
            return {"energy_wh_per_km": wall * p["charger_efficiency"], "energy_wall_wh_per_km": wall,
                    "drive_torque_margin_nm": np.minimum.reduce([c.torque_margin_nm for _, c in runs]),
                    "drive_power_margin_kw": np.minimum.reduce([c.power_margin_kw for _, c in runs])}
        # e.g. EPA combined: 0.55 UDDS + 0.45 HWFET by distance (one cycle: 0 + 1.0 x, the same bits)
        e = sum(w * self._fn(r, p, inputs["vehicle_mass_kg"], inputs["gear_ratio"], motor_kw)
                for w, r in self._cycles())
        if self.energy_model == "chain":  # the chain's energy is from the wall; the battery gives E_wall x eta_chg
            return {"energy_wh_per_km": e * p["charger_efficiency"], "energy_wall_wh_per_km": e}
        return {"energy_wh_per_km": e}


# An energy model's margins over its cycle (option feasibility_outputs): one below 0 is a design that does not
# follow the cycle. A Taycan-like DM-DA optimum turned its rear motor 156 rad/s past its limit on a motorway
# cycle (motor_speed_margin_rad_s -155.8) while the note said only that the steps are not checked.
FOLLOW_MARGINS = ("drive_torque_margin_nm", "motor_speed_margin_rad_s", "drive_power_margin_kw", "drive_force_margin_n")


def _follow_margins(d, values: Mapping) -> dict:
    """{margin: value(s)} of ``FOLLOW_MARGINS`` that discipline ``d`` gives and ``values`` holds."""
    return {k: values[k] for k in FOLLOW_MARGINS if k in getattr(d, "outputs", ()) and values.get(k) is not None}


def follow_notes(disciplines, values: Mapping) -> tuple[list[str], list[str]]:
    """(one line per discipline of ``disciplines`` (a run's) that says the one design in ``values`` cannot follow
    its drive cycle, e.g. a van asked for 0-60 km/h in 1 s; one line per discipline that cannot check it for this
    design): the energy discipline's ``cycle_steps_short``, run once."""
    short, unchecked = [], []
    for d in disciplines:
        if getattr(d, "envelope", None) is None:
            continue
        rows = d.cycle_steps_short(values)
        margins = _follow_margins(d, values)
        if (rows is None or rows[0][2][0] < 0) and margins:  # the model's own margins say it
            if below := {k: float(np.ravel(v)[0]) for k, v in margins.items() if np.ravel(v)[0] < 0}:
                short.append(f"{d.name}: the design cannot follow its cycle (" + ", ".join(
                    f"{k} {v:.4g}" for k, v in below.items()) + "): its energy per km is that of the cycle's demand, "
                    "not of a powertrain that follows it")
        elif rows is None or rows[0][2][0] < 0:
            unchecked.append(f"{d.name}: whether the motor can follow the cycle is not checked for this gearbox or "
                             "topology (the check covers single-speed SM-SA); energy options {feasibility_outputs: "
                             "true} give the model's margins")
        elif line := d.cannot_follow(values, rows):
            short.append(line)
    return short, unchecked


def follow_counts(disciplines, values: Mapping) -> tuple[np.ndarray, np.ndarray]:
    """(cannot follow, not checked) per design of a batch (``values``: (N,) columns): boolean arrays over
    the run's disciplines and cycles (``cycle_steps_short``)."""
    n = len(next(iter(values.values())))
    short, unchecked = np.zeros(n, bool), np.zeros(n, bool)
    for d in disciplines:
        if getattr(d, "envelope", None) is None:
            continue
        margins = _follow_margins(d, values)
        below = np.logical_or.reduce([np.asarray(v) < 0 for v in margins.values()]) if margins else None
        for _, _, count, *_ in d.cycle_steps_short(values) or [(None, None, np.full(n, -1), None)]:
            short |= count > 0
            if below is not None:  # where the steps are not checked, the model's margins are
                short |= (count < 0) & below
            else:
                unchecked |= count < 0
    return short, unchecked


def follow_batch(disciplines):
    """``follow_check`` of a batch: ``check(values)`` -> (N,) bool, True where a design cannot follow its cycle
    (``follow_counts``, one call for the batch); None when no discipline of ``disciplines`` checks it."""
    discs = tuple(d for d in disciplines if getattr(d, "envelope", None) is not None)
    return (lambda values: follow_counts(discs, values)[0]) if discs else None


def follow_check(disciplines):
    """The run's judgement of a design beyond its constraints (RunSettings.design_check): ``check(values)`` ->
    ``follow_notes``' lines that the one design in ``values`` cannot follow its cycle ([] when it can); None when
    no discipline of ``disciplines`` checks it."""
    discs = tuple(d for d in disciplines if getattr(d, "envelope", None) is not None)
    return (lambda values: follow_notes(discs, values)[0]) if discs else None


def battery_margins(results, final_soc) -> dict:
    """The battery's margins over quasi-static results (one per cycle), the tightest of them: power (kW, at
    most 1e9 for a cycle that never draws), SOC above ``final_soc`` and the discharge current's share of its
    limit left (at most 1)."""
    power_kw = np.minimum(np.minimum.reduce([r.battery_power_margin_kw for r in results]), 1e9)
    return {"battery_power_margin_kw": power_kw,
            "battery_soc_margin": np.minimum.reduce([r.soc_min for r in results]) - np.asarray(final_soc, float),
            "battery_current_margin": np.minimum(np.minimum.reduce([r.battery_current_margin for r in results]), 1.0)}


def _cycle_weights(config, options, model):
    """Energy option ``cycle_weights: {cycle: distance share, ...}`` (shares summing to 1): the energy per km
    is the distance-weighted mean over those cycles, e.g. EPA combined {epa_udds: 0.55, epa_hwfet: 0.45}."""
    cw = options.cycle_weights
    if cw is None:
        return None
    if not isinstance(cw, Mapping) or not cw:
        raise ValueError("energy option cycle_weights must map cycle names to distance shares")
    total = 0.0
    out = []
    for name, w in cw.items():
        if isinstance(w, bool) or not isinstance(w, (int, float)) or not 0 < w <= 1:
            raise ValueError(f"energy option cycle_weights.{name} must be a share in (0, 1], got {w!r}")
        total += float(w)
        out.append((float(w), resampled_cycle(config, name)))
    if abs(total - 1.0) > 1e-9:
        raise ValueError(f"energy option cycle_weights must sum to 1, got {total:g}")
    return out


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
        self.units = {**self.units, self.outputs[0]: "km"}

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
    return re.sub(r"[^a-z0-9]+", "_", str(name).lower()).strip("_") or "cycle"


def warm_up() -> float:
    """Compile (or load from numba's on-disk cache) every compiled loop of the quasi-static and topology models:
    energy and range of each topology, with the packaged motor map and with the loss model, on a 3-step cycle.
    Returns the seconds taken: about a minute on a small host the first time after an install, a fraction of a
    second once cached. ``scripts/setup.sh`` runs it after installing; ``Energy.prepare`` before the first call."""
    start = time.perf_counter()
    note = threading.Timer(3.0, lambda: print("note: compiling the quasi-static model's loops (numba), once after an "
                                              "install: about a minute on a small host", file=sys.stderr, flush=True))
    note.daemon = True
    note.start()
    cycle = resample(DriveCycle("warm_up", np.array([0.0, 1.0, 2.0, 3.0]), np.array([0.0, 2.0, 2.0, 0.0])), 1.0)
    args = tuple(np.array([x]) for x in (1500.0, 80.0, 24.0, 8.0, 40.0, 8.0))  # mass, kW, kWh, ratio, rear kW, ratio
    for loss_model in (0.0, 1.0):
        for t in topo_model.TOPOLOGIES:
            topo_model.simulate(cycle, {"motor_loss_model": loss_model}, t, *args)
            topo_model.range_by_repeated_cycle_km(cycle, {"motor_loss_model": loss_model}, t, *args, max_repeats=1)
    note.cancel()
    return time.perf_counter() - start
