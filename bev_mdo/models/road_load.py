"""Road load as users measure it: F = A + B v + C v^2 from a coast-down (EPA target coefficients).

``vehicle.road_load: {a_n, b_n_per_m_s, c_n_per_m2_s2[, mass_kg]}`` replaces the drag-area and
rolling-resistance terms of the thesis' eq 2-3 / 7-18 (1/2 rho C_dA v^2 + C_r M g) in every
energy model and in the acceleration model. A coast-down already contains tyre rolling
resistance, aerodynamic drag and the drivetrain's spin losses (bearings, gear churning, a
permanent-magnet motor's no-load iron loss), so a model fed with it must not add those again.

``mass_kg`` (optional) is the test mass the coefficients were measured at. Given, A scales
with the vehicle mass (A M / mass_kg: rolling resistance is the mass-proportional part of A),
so an optimisation that changes the mass still sees a consistent road load; not given, A is
fixed. The road load acts only while the vehicle moves (v > 0).

The parameters travel flat through the models as ``road_load_a_n``, ``road_load_b_n_per_m_s``,
``road_load_c_n_per_m2_s2`` and ``road_load_mass_kg`` (0 = A fixed).
"""
from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from .params import ParamSpec, check_value

ROAD_LOAD_SPECS: dict[str, tuple[str, ParamSpec]] = {
    "a_n": ("road_load_a_n", ParamSpec(0.0, 0.0, 5000.0, "N", "constant road-load term A")),
    "b_n_per_m_s": ("road_load_b_n_per_m_s", ParamSpec(0.0, -100.0, 100.0, "N/(m/s)", "linear term B")),
    "c_n_per_m2_s2": ("road_load_c_n_per_m2_s2", ParamSpec(0.0, 0.0, 5.0, "N/(m/s)^2", "quadratic term C")),
    "mass_kg": ("road_load_mass_kg", ParamSpec(0.0, 100.0, 20000.0, "kg", "test mass of the coast-down "
                                                                        "(A scales with M / mass_kg)")),
}
FLAT_KEYS = tuple(k for k, _ in ROAD_LOAD_SPECS.values())
CHECK_SPEED_M_S = 70.0  # the force must stay positive from 0 to 252 km/h


def validate_road_load(section: Any) -> dict[str, float]:
    """The ``vehicle.road_load`` mapping as the flat ``road_load_*`` parameters; one-line ValueError."""
    if not isinstance(section, Mapping):
        raise ValueError("road_load must be a mapping {a_n, b_n_per_m_s, c_n_per_m2_s2[, mass_kg]}")
    unknown = sorted(set(section) - set(ROAD_LOAD_SPECS))
    if unknown:
        raise ValueError(f"road_load: unknown key(s) {unknown}; known: {sorted(ROAD_LOAD_SPECS)}")
    missing = [k for k in ("a_n", "b_n_per_m_s", "c_n_per_m2_s2") if k not in section]
    if missing:
        raise ValueError(f"road_load: missing {missing} (all of a_n, b_n_per_m_s, c_n_per_m2_s2 are needed)")
    out = {"road_load_mass_kg": 0.0}
    for k, (flat_name, s) in ROAD_LOAD_SPECS.items():
        if k in section:
            out[flat_name] = check_value(f"road_load.{k}", section[k], s.lower, s.upper, s.unit)
    a, b, c = out["road_load_a_n"], out["road_load_b_n_per_m_s"], out["road_load_c_n_per_m2_s2"]
    v = np.linspace(0.0, CHECK_SPEED_M_S, 701)
    f = a + b * v + c * v * v
    if f.min() <= 0.0:
        raise ValueError(f"road_load: A + B v + C v^2 must stay > 0 up to {CHECK_SPEED_M_S:g} m/s; it is "
                         f"{f.min():.4g} N at {v[np.argmin(f)]:.3g} m/s")
    return out


def uses_road_load(params: Mapping[str, Any] | None) -> bool:
    """True when ``params`` carry coast-down coefficients (they then replace C_dA and C_r)."""
    return bool(params) and "road_load_c_n_per_m2_s2" in params


def coefficients(params: Mapping[str, Any]) -> tuple[Any, Any, Any, Any]:
    """(A fixed part in N, A per kg of vehicle mass in N/kg, B, C) of a road-load parameter set."""
    a = np.asarray(params["road_load_a_n"], float)
    m_ref = np.asarray(params.get("road_load_mass_kg", 0.0), float)
    scaled = m_ref > 0
    a_per_kg = np.where(scaled, a / np.where(scaled, m_ref, 1.0), 0.0)
    a_fixed = np.where(scaled, 0.0, a)
    b = np.asarray(params["road_load_b_n_per_m_s"], float)
    c = np.asarray(params["road_load_c_n_per_m2_s2"], float)
    return (_scalar(a_fixed), _scalar(a_per_kg), _scalar(b), _scalar(c))


def _scalar(x):
    return float(x) if np.ndim(x) == 0 else x


def force_n(params: Mapping[str, Any], speed_m_s, mass_kg) -> np.ndarray:
    """Road-load force A + B v + C v^2 (N) at speeds >= 0, zero at standstill; broadcasts."""
    a0, a1, b, c = coefficients(params)
    v = np.asarray(speed_m_s, float)
    return np.where(v > 0, a0 + a1 * mass_kg + b * v + c * v * v, 0.0)
