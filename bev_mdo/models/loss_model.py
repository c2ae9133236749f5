"""Motor and inverter losses in torque, speed and rated power: the loss model behind the thesis' map.

The thesis' quasi-static model looks the motor's efficiency up in a map of torque and speed
(eqs 2-7, 2-8) whose torque axis scales with the rated power (Fig 2-9). bev_mdo's default map is
itself drawn from a loss model (motor_map.py). Read under Fig 2-9's scaling, that map makes every
loss that does not depend on torque (iron, friction, inverter idle) grow in proportion to the
rated power: a 400 kW motor idles with five times the loss of the 80 kW one, which the EPA fleet
refutes (docs/validation.md). ``LossModel`` writes the losses out instead, one term per cause,
so their size scaling can be fitted to measured cars (``calibrate.py``):

    P_el = T w + L(T, w, P)          (eq 2-7 written with the loss instead of the efficiency)
    L    = k_cu T^2 (P_ref / P)      copper: R I^2 (eq 6-27) with I = T / K_m (eq 6-21); R / K_m^2
                                     scales as Fig 2-9's torque axis
         + k_inv |T|                 inverter conduction: ~ phase current ~ T (eq 6-21); size-free
                                     under Fig 2-9's scaling
         + (P / P_ref)^e (k_fe w + k_fr w^2 + P_0)
                                     iron (hysteresis ~ w), friction and windage (eq 6-18's
                                     b w_m torque: b w^2) and the inverter's switching/idle loss;
                                     e = 1 is Fig 2-9's scaling, e < 1 what the fleet shows

while the motor turns (w > 0; at standstill nothing). Regenerating, T w < 0 and the loss is
still added, so a motor braking gently can draw power. The gear loss stays eq 2-5's mesh
efficiency. The coefficients belong to a motor of ``reference_kw``.

A second driven axle (``driven_axles = 2`` in the quasi-static model, an all-wheel-drive car
described by its total rated power) is two machines of P/2 sharing the torque equally, plus
``second_axle_drag_w`` of gear and bearing drag while the car moves. With e = 1 the two machines
lose what one of P loses; with e < 1 their idle losses add up to more. The in-wheel topologies
get their own: the model with its axes scaled as §4.3.1 scales the map (:meth:`LossModel.scaled`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# parameter name -> LossModel field (QUASI_STATIC_SPECS holds the units, defaults and ranges)
PARAMETERS = {
    "loss_copper_w_per_nm2": "copper_w_per_nm2",
    "loss_inverter_w_per_nm": "inverter_w_per_nm",
    "loss_iron_w_s_per_rad": "iron_w_s_per_rad",
    "loss_friction_w_s2_per_rad2": "friction_w_s2_per_rad2",
    "loss_constant_w": "constant_w",
    "loss_size_exponent": "size_exponent",
}


@dataclass(frozen=True)
class LossModel:
    """Loss coefficients of a motor of ``reference_kw`` (see the module docstring)."""

    copper_w_per_nm2: float
    inverter_w_per_nm: float
    iron_w_s_per_rad: float
    friction_w_s2_per_rad2: float
    constant_w: float
    size_exponent: float
    reference_kw: float = 80.0
    name: str = "loss_model"

    @classmethod
    def from_params(cls, p: dict, reference_kw: float = 80.0) -> "LossModel":
        """The model of the resolved parameters ``p``; the coefficients must be one value for
        every design point (one model per batch, as one map)."""
        values = {}
        for key, attr in PARAMETERS.items():
            a = np.atleast_1d(np.asarray(p[key], float))
            if np.ptp(a):
                raise ValueError(f"{key} must be the same for every design point")
            values[attr] = float(a[0])
        return cls(**values, reference_kw=float(reference_kw))

    def scaled(self, torque_scale: float, speed_scale: float) -> "LossModel":
        """The model of a motor whose torque and speed axes are scaled (§4.3.1, the in-wheel motor),
        as ``topology.in_wheel_map`` scales a map: L'(T, w) = ts ss L(T / ts, w / ss)."""
        ts, ss = float(torque_scale), float(speed_scale)
        return LossModel(self.copper_w_per_nm2 * ss / ts, self.inverter_w_per_nm * ss, self.iron_w_s_per_rad * ts,
                         self.friction_w_s2_per_rad2 * ts / ss, self.constant_w * ts * ss, self.size_exponent,
                         self.reference_kw * ts * ss, f"{self.name}_in_wheel")

    def loss_w(self, torque_nm, speed_rad_s, motor_kw):
        """L(T, w, P) in W while the motor turns, 0 at standstill (arrays broadcast together)."""
        t = np.asarray(torque_nm, float)
        w = np.abs(np.asarray(speed_rad_s, float))
        scale = self.reference_kw / np.asarray(motor_kw, float)  # P_ref / P, as the map's torque scaling
        loss = (self.copper_w_per_nm2 * t * t * scale + self.inverter_w_per_nm * np.abs(t)
                + (self.iron_w_s_per_rad * w + self.friction_w_s2_per_rad2 * w * w + self.constant_w)
                / scale ** self.size_exponent)
        return np.where(w > 0, loss, 0.0)

    def electrical_power_w(self, torque_nm, speed_rad_s, motor_kw):
        """P_el = T w + L (W): > 0 drawn, < 0 returned (eq 2-7 with the loss written out)."""
        t = np.asarray(torque_nm, float)
        return t * np.asarray(speed_rad_s, float) + self.loss_w(t, speed_rad_s, motor_kw)

    def as_tuple(self) -> tuple:
        """Coefficients as the compiled loops take them."""
        return (self.copper_w_per_nm2, self.inverter_w_per_nm, self.iron_w_s_per_rad,
                self.friction_w_s2_per_rad2, self.constant_w, self.size_exponent)

