"""Motor speed constraint (eq 7-29): the highest motor speed the cycle demands."""
from __future__ import annotations

import numpy as np

from .common import check_array, check_design
from .params import VEHICLE_SPECS


def motor_speed_max_rad_s(gear_ratio, max_speed_m_s, wheel_radius_m=VEHICLE_SPECS["wheel_radius_m"].default,
                          two_speed=None):
    """Eqs 7-24/7-29: omega_max = i_g v_max / r_w (rad/s). ``two_speed``: (gear_ratio_2, shift_speed_m_s) of a
    two-speed gearbox shifting by speed (eq 2-6): first gear up to the shift speed, the second above it,
    so omega_max = max(i_g min(v_max, v_shift), i_g2 v_max [v_max >= v_shift]) / r_w."""
    ig = check_design("gear_ratio", gear_ratio)
    s = VEHICLE_SPECS["wheel_radius_m"]
    rw = check_array("wheel_radius_m", wheel_radius_m, s.lower, s.upper, s.unit)
    v = check_array("max_speed_m_s", max_speed_m_s, 0.0, 150.0, "m/s")
    if two_speed is None:
        return ig * v / rw
    ig2, shift = (np.asarray(x, float) for x in two_speed)
    return np.maximum(ig * np.minimum(v, shift), np.where(v >= shift, ig2 * v, 0.0)) / rw
