"""Motor speed constraint (eq 7-29): the highest motor speed the cycle demands."""
from __future__ import annotations

import numpy as np

from .common import check_array, check_design
from .params import VEHICLE_SPECS


def motor_speed_max_rad_s(gear_ratio, max_speed_m_s, wheel_radius_m=VEHICLE_SPECS["wheel_radius_m"].default):
    """Eqs 7-24/7-29: omega_max = i_g v_max / r_w (rad/s)."""
    ig = check_design("gear_ratio", gear_ratio)
    s = VEHICLE_SPECS["wheel_radius_m"]
    rw = check_array("wheel_radius_m", wheel_radius_m, s.lower, s.upper, s.unit)
    v = check_array("max_speed_m_s", max_speed_m_s, 0.0, 150.0, "m/s")
    return ig * v / rw
