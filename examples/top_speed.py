"""A user's own discipline, served by the generic node with no change to bev_mdo.

Top speed on a flat road: the speed at which the motor's peak power at the wheels
equals the road load, capped by the motor's maximum speed through the gear.
    P_max * eta_g = (0.5 * rho * CdA * v^2 + Cr * M * g) * v,   v <= omega_max * r_w / i_g
Use it from a config:
    disciplines:
      - vehicle_mass
      - energy
      ...
      - {name: top_speed, class: "examples.top_speed:TopSpeed", options: {motor_max_speed_rad_s: 1100}}
    problem:
      constraints:
        top_speed_kmh: {lower: 140}
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


class TopSpeed:
    """inputs motor_kw, gear_ratio, vehicle_mass_kg -> top_speed_kmh (batched)."""

    name = "top_speed"
    inputs = ("motor_kw", "gear_ratio", "vehicle_mass_kg")
    outputs = ("top_speed_kmh",)
    units = {"motor_kw": "kW", "gear_ratio": "1", "vehicle_mass_kg": "kg", "top_speed_kmh": "km/h"}
    parameters = {}

    def __init__(self, drag_area_m2=0.6412, rolling_resistance=0.007, air_density_kg_m3=1.25,
                 gravity_m_s2=9.81, gear_efficiency=0.97, wheel_radius_m=0.316, motor_max_speed_rad_s=1100.0):
        if motor_max_speed_rad_s <= 0:
            raise ValueError(f"motor_max_speed_rad_s must be > 0, got {motor_max_speed_rad_s}")
        self.a = 0.5 * air_density_kg_m3 * drag_area_m2
        self.cr_g = rolling_resistance * gravity_m_s2
        self.eta = gear_efficiency
        self.r_w = wheel_radius_m
        self.omega_max = motor_max_speed_rad_s

    @dataclass(frozen=True)
    class Options:
        """The config entry's options (any other key is refused when the config is loaded)."""

        motor_max_speed_rad_s: float = 1100.0

    @classmethod
    def from_config(cls, config, options):
        """Take the vehicle constants from the run config, the motor's speed limit from the options."""
        v = config.get("vehicle", {})
        keys = ("drag_area_m2", "rolling_resistance", "air_density_kg_m3", "gravity_m_s2", "gear_efficiency",
                "wheel_radius_m")
        return cls(**{k: v[k] for k in keys if k in v}, motor_max_speed_rad_s=options.motor_max_speed_rad_s)

    def compute(self, inputs):
        p_w = inputs["motor_kw"] * 1e3 * self.eta
        b = self.cr_g * inputs["vehicle_mass_kg"]
        v = np.cbrt(p_w / self.a)                      # upper bound: aerodynamic load alone
        for _ in range(30):                           # Newton on a v^3 + b v - P = 0 (monotonic)
            v = v - (self.a * v**3 + b * v - p_w) / (3 * self.a * v**2 + b)
        v_gear = self.omega_max * self.r_w / inputs["gear_ratio"]
        return {"top_speed_kmh": np.minimum(v, v_gear) * 3.6}
