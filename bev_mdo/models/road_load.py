"""Road load, the one function every model uses: the thesis' eq 2-3 / 7-18 or a coast-down.

Both forms are F_road = (A0 + A1 M) sgn(v) + B v + C v|v| (:func:`coefficients`): the thesis'
1/2 rho C_dA v|v| + C_r M g sgn(v) (rolling resistance acts while the vehicle moves), or the
coast-down A + B v + C v^2 while moving (EPA target coefficients), zero at standstill.
:func:`road_load_n` is the force; :func:`road_load_terms` the same force split as f_0(v) + f_M(v) M
(with df_0/dv) for the models that precompute cycle moments.

Road load as users measure it: F = A + B v + C v^2 from a coast-down (EPA target coefficients).

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
``road_load_c_n_per_m2_s2`` and ``road_load_mass_kg`` (0 = A fixed); their specs and the
validation of the ``vehicle.road_load`` section are in params.py.
"""
from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from .params import ROAD_LOAD_SPECS

FLAT_KEYS = tuple(k for k, _ in ROAD_LOAD_SPECS.values())


# Where measured BEVs lie (the shipped training fleet, bev_mdo/data/epa_2022_bev/train.csv: median, factor): generous
# (its 62 cars span A/(m g) 0.0050-0.0115 and C 0.22-0.52) yet inside the unit mix-ups' ratios: EPA's own lbf is
# 1/4.45 x N, lbf/mph^2 1/22.3 x N/(m/s)^2, N/(km/h)^2 1/13 x, lb 2.2 x kg. models.fleet checks a fleet's medians by them.
TYPICAL_A_OVER_MG = (0.00725, 1.6)
TYPICAL_C_N_PER_M2_S2 = (0.374, 3.0)
ONE_CAR_A_FACTOR = 2.0  # one car's A/(m g), not a fleet's median: EPA's 2022 BEVs span 0.0044 (Ioniq 5) - 0.0115
G_M_S2 = 9.81


def implausible_note(params: Mapping[str, Any]) -> str | None:
    """One line where a coast-down's C (or A against its test mass, when given) lies outside where measured cars do:
    EPA's published coefficients pasted in lbf, lbf/mph and lbf/mph^2 ran as a car using a third of its energy
    with no word. A note, not a refusal (an unusual vehicle may be meant); None when plausible or no coast-down."""
    if not uses_road_load(params):
        return None
    out = []
    c, (c_typ, c_fac) = float(params["road_load_c_n_per_m2_s2"]), TYPICAL_C_N_PER_M2_S2
    if not c_typ / c_fac <= c <= c_typ * c_fac:
        out.append(f"c_n_per_m2_s2 {c:g} is outside [{c_typ / c_fac:.3g}, {c_typ * c_fac:.3g}] where measured cars lie "
                   f"(lbf/mph^2 is 1/22.3 of N/(m/s)^2, N/(km/h)^2 1/13)")
    mass = float(params.get("road_load_mass_kg", 0.0))
    if mass > 0.0:
        ratio, (typ, fac) = float(params["road_load_a_n"]) / (mass * G_M_S2), (TYPICAL_A_OVER_MG[0], ONE_CAR_A_FACTOR)
        if not typ / fac <= ratio <= typ * fac:
            out.append(f"a_n / (mass_kg g) {ratio:.3g} is outside [{typ / fac:.3g}, {typ * fac:.3g}] (a_n in lbf is "
                       "1/4.45 of N; mass_kg in lb 2.2 x kg)")
    return "; ".join(out) + ": a unit mix-up? (read as given)" if out else None


def uses_road_load(params: Mapping[str, Any] | None) -> bool:
    """True when ``params`` carry coast-down coefficients (they then replace C_dA and C_r)."""
    return bool(params) and "road_load_c_n_per_m2_s2" in params


def check_values(params: Mapping[str, Any]) -> None:
    """ValueError unless the ``road_load_*`` values in ``params`` (scalars or (N,) arrays, e.g. a per-point
    override) are what ``vehicle.road_load`` accepts: each in its range (``road_load_mass_kg`` 0 = A fixed)
    and A + B v + C v^2 > 0 up to ROAD_LOAD_CHECK_SPEED_M_S for every point."""
    from .common import check_array
    from .params import ROAD_LOAD_CHECK_SPEED_M_S, road_load_minimum

    for flat, s in ROAD_LOAD_SPECS.values():
        if flat in params:
            x = np.asarray(params[flat], float)
            if flat == "road_load_mass_kg":
                x = np.where(x == 0.0, s.lower, x)  # 0: A does not scale with the mass
            check_array(flat, x, s.lower, s.upper, s.unit)
    if uses_road_load(params):
        a, b, c = (np.atleast_1d(np.asarray(params.get(k, 0.0), float)) for k in FLAT_KEYS[:3])
        low, _ = road_load_minimum(a, b, c)
        if (low <= 0.0).any():
            i = int(np.argmin(low))
            raise ValueError(f"road load A + B v + C v^2 must stay > 0 up to {ROAD_LOAD_CHECK_SPEED_M_S:g} m/s; "
                             f"it is {low[i]:.4g} N (A {a[i % a.size]:g}, B {b[i % b.size]:g}, C {c[i % c.size]:g})")


def checked(params: Mapping[str, Any] | None) -> dict[str, Any]:
    """The coast-down values in ``params`` as a model takes them (scalars or (N,) arrays; the keys left
    out are 0), checked as ``vehicle.road_load`` is (:func:`check_values`); {} without a coast-down.
    Every model reads them through here: a NaN A crashed the compiled loops, a negative one gave a
    negative energy."""
    if not uses_road_load(params):
        return {}
    out = {k: _scalar(np.asarray(params.get(k, 0.0), float)) for k in FLAT_KEYS}
    check_values(out)
    return out


def coefficients(params: Mapping[str, Any]) -> tuple[Any, Any, Any, Any]:
    """(A0, A1, B, C) of the road load F = (A0 + A1 M) sgn(v) + B v + C v|v| (N; M in kg, v in m/s).

    Coast-down: A0 = A (0 when it scales with the mass), A1 = A / mass_kg (0 when fixed), B, C.
    Thesis (eq 2-3 / 7-18): A0 = 0, A1 = C_r g, B = 0, C = 1/2 rho C_dA."""
    if not uses_road_load(params):
        return (0.0, params["rolling_resistance"] * params["gravity_m_s2"], 0.0,
                0.5 * params["air_density_kg_m3"] * params["drag_area_m2"])
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


def road_load_n(params: Mapping[str, Any], speed_m_s, mass_kg) -> np.ndarray:
    """Road-load force (N) at ``speed_m_s`` (>= 0) for a vehicle of ``mass_kg``: eq 2-3 / 7-18, or the
    coast-down A + B v + C v^2; zero at standstill. Broadcasts speeds against designs."""
    a0, a1, b, c = coefficients(params)
    v = np.asarray(speed_m_s, float)
    base = a0 + a1 * mass_kg
    if v.size and v.min() > 0:  # moving throughout (the usual case): sgn(v) = 1, v|v| = v^2
        return base + v * (b + c * v)
    return base * np.sign(v) + v * (b + c * np.abs(v))


def road_load_terms(params: Mapping[str, Any], speed_m_s) -> tuple[Any, Any, Any]:
    """The same road load split as F_road = f_0 + f_M M, with the rate df_0/dv: (f_0, f_M, df_0/dv),
    for the models that precompute cycle moments independent of the mass (flat.py)."""
    a0, a1, b, c = coefficients(params)
    v = np.asarray(speed_m_s, float)
    s, speed = np.sign(v), np.abs(v)
    return a0 * s + v * (b + c * speed), a1 * s, b + 2.0 * c * speed
