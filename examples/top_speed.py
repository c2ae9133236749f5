"""A user's own discipline, served by the generic node with no change to bev_mdo.

Top speed on a flat road: the speed at which the motor's peak force at the wheels equals the road load,
capped by the motor's maximum speed through the gear. The force is the motor's envelope, as the acceleration
model takes it: its peak torque tau * P_max up to the base speed, its peak power above (Fig 2-9):
    min(tau P_max i_g eta_g / r_w, P eta_g / v) = 0.5 * rho * CdA * v^2 + Cr * M * g,   v <= omega_max * r_w / i_g
where P is the motor's peak power, or the pack's power at the shaft where that is less (as the acceleration model
takes it: models.acceleration.battery_shaft_power_w). With two speeds the faster of the two gears.
With a coast-down in the config (``vehicle.road_load``) the road load is that one, A + B v + C v^2,
as the built-in models take it (bev_mdo.models.road_load).
One motor and its gear (SM-SA): with a second motor (DM-DA) it sees only `motor_kw` and `gear_ratio`, so
the rear motor's power and its speed limit through `gear_ratio_rear` are not counted (a rear axle that
cannot disconnect caps the top speed at its own limit: add that as a constraint of your own).
Use it from a config:
    disciplines:
      - vehicle_mass
      - energy
      ...
      - {name: top_speed, class: "examples.top_speed:TopSpeed"}
    problem:
      constraints:
        top_speed_kmh: {lower: 140}
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from bev_mdo.models.acceleration import battery_shaft_power_w
from bev_mdo.models.cycles import CycleNote
from bev_mdo.models.params import ROAD_LOAD_UNUSED, all_specs, validate_road_load, validate_vehicle, vehicle_choice
from bev_mdo.models.road_load import coefficients


class TopSpeed:
    """inputs motor_kw, gear_ratio, vehicle_mass_kg, battery_kwh -> top_speed_kmh (batched).

    The vehicle constants it reads are its ``parameters`` ({name: the run config's value}): a run that
    overrides one (``--set``, ``--vary``, ``sensitivity --wrt``, ``problem.parameters``) sends it as an
    input column of that name, which ``compute`` takes in place of the configured value."""

    name = "top_speed"
    inputs = ("motor_kw", "gear_ratio", "vehicle_mass_kg", "battery_kwh")
    outputs = ("top_speed_kmh",)
    units = {"motor_kw": "kW", "gear_ratio": "1", "vehicle_mass_kg": "kg", "battery_kwh": "kWh", "top_speed_kmh": "km/h"}
    VEHICLE_CONSTANTS = ("drag_area_m2", "rolling_resistance", "air_density_kg_m3", "gravity_m_s2",
                         "gear_efficiency", "wheel_radius_m", "gear_count", "gear_ratio_2", "motor_speed_limit_rpm",
                         "motor_torque_per_kw",  # gear_count, gear_ratio_2: a two-speed gearbox
                         "battery_to_shaft_efficiency", "cells_series", "initial_soc", "discharge_c_max")  # the pack

    def __init__(self, motor_max_speed_rad_s=None, road_load=None, **constants):
        """``constants``: any of VEHICLE_CONSTANTS; the others take bev_mdo's defaults (models.params)."""
        if motor_max_speed_rad_s is not None and motor_max_speed_rad_s <= 0:
            raise ValueError(f"motor_max_speed_rad_s must be > 0, got {motor_max_speed_rad_s}")
        unknown = sorted(set(constants) - set(self.VEHICLE_CONSTANTS))
        if unknown:
            raise TypeError(f"TopSpeed does not read {', '.join(unknown)}")
        defaults = all_specs()
        self.parameters = {**{k: constants.get(k, defaults[k].default) for k in self.VEHICLE_CONSTANTS},
                           **(validate_road_load(road_load) if road_load else {})}  # road_load_a_n, ...
        if road_load:  # a coast-down replaces these: a parameter no formula reads must not be offered for overrides
            self.parameters = {k: x for k, x in self.parameters.items() if k not in ROAD_LOAD_UNUSED}
        self.omega_max = motor_max_speed_rad_s  # None: the vehicle's motor_speed_limit_rpm, as the built-in models

    @dataclass(frozen=True)
    class Options:
        """The config entry's options (any other key is refused when the config is loaded)."""

        motor_max_speed_rad_s: float | None = None  # default: the vehicle's motor_speed_limit_rpm (one limit, not two)

    @classmethod
    def from_config(cls, config, options):
        """Take the vehicle constants from the run config, a named parameter set's and the defaults as the built-in
        models take them; the motor's speed limit too, unless the options give one."""
        v = validate_vehicle(config.get("vehicle"))
        if (topology := vehicle_choice(config.get("vehicle"), "topology")) != "SM-SA":  # a two-motor EV6: 179 km/h,
            warnings.warn(f"top_speed (examples/top_speed.py) counts one motor and its gear: of a {topology} vehicle "
                          "the front motor alone (motor_kw, gear_ratio)", CycleNote, stacklevel=2)  # its front's, unsaid
        return cls(**{k: v[k] for k in cls.VEHICLE_CONSTANTS if k in v}, road_load=config.get("vehicle", {}).get(
            "road_load"), motor_max_speed_rad_s=options.motor_max_speed_rad_s)

    def compute(self, inputs):
        p = {k: inputs.get(k, value) for k, value in self.parameters.items()}  # a per-point override wins
        a0, a1, b, c = coefficients(p)                # road load F = a0 + a1 M + b v + c v^2 (N)
        f0 = a0 + a1 * inputs["vehicle_mass_kg"]
        p_w = np.minimum(inputs["motor_kw"] * 1e3, battery_shaft_power_w(inputs["battery_kwh"], p)) * p["gear_efficiency"]
        omega_max = p["motor_speed_limit_rpm"] * np.pi / 30.0 if self.omega_max is None else self.omega_max
        first = inputs["gear_ratio"]
        second = np.where(p["gear_count"] == 2, p["gear_ratio_2"], first)
        torque_nm = p["motor_torque_per_kw"] * inputs["motor_kw"]  # the motor's peak torque (N m)
        return {"top_speed_kmh": np.maximum(self._in_gear(first, f0, b, c, p_w, torque_nm, omega_max, p),
                                            self._in_gear(second, f0, b, c, p_w, torque_nm, omega_max, p)) * 3.6}

    @staticmethod
    def _in_gear(gear_ratio, f0, b, c, p_w, torque_nm, omega_max, p):
        """Top speed (m/s) in one gear: where the road load meets the motor's force envelope, at most the gear's
        speed cap. The load rises with v and the envelope does not, so bisection finds the one crossing."""
        torque_force_n = torque_nm * gear_ratio * p["gear_efficiency"] / p["wheel_radius_m"]
        lo, hi = np.zeros_like(p_w), np.cbrt(p_w / c) + np.abs(b) / c + 1.0  # F(hi) hi > P_w
        for _ in range(60):
            v = 0.5 * (lo + hi)
            above = f0 + b * v + c * v * v > np.minimum(torque_force_n, p_w / np.maximum(v, 1e-300))
            lo, hi = np.where(above, lo, v), np.where(above, v, hi)
        return np.minimum(0.5 * (lo + hi), omega_max * p["wheel_radius_m"] / gear_ratio)
