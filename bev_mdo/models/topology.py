"""Powertrain topologies of thesis chapter 4: SM-SA, DM-DA, IWM-SA, IWM-DA.

=========  ===========================  ==========================  =====================
topology   motors (front + rear)        drive                        design variables
=========  ===========================  ==========================  =====================
SM-SA      1 (front)                    single ratio (two-speed      motor_kw, gear_ratio,
                                        optional, §2.2.2)            battery_kwh
DM-DA      1 + 1                        one single ratio per axle    + motor_rear_kw,
                                                                     gear_ratio_rear
IWM-SA     2 in-wheel (front)           direct drive, eta = 1        motor_kw, battery_kwh
IWM-DA     2 + 2 in-wheel               direct drive, eta = 1        + motor_rear_kw
=========  ===========================  ==========================  =====================

``motor_kw`` / ``motor_rear_kw`` are the power of EACH motor of that axle (Table 4-4: "40 kW, 42.88 kg,
2"). The battery, SOC and §2.3.4 regeneration rules 2-4 are the quasi-static model's. Rules:

* mass (Tables 4-1, 4-2, 4-4): motor unit = sum of eq 2-18 over the motors; DM-DA adds
  ``dm_da_transmission_kg`` (30 kg); in-wheel x ``iwm_mass_factor`` (0.75, "25 % removed"). Table 4-4's
  "difference from the Leaf" is the motor-unit difference (Table 4-5 = 1521 kg + it: the ``ch7`` mass
  model; ``compounding`` multiplies it by 1.6). The battery is the same for every topology.
* cost (Table 4-3, eq 4-4): motor cost eq 2-21 per motor, pack eqs 4-2/4-3; ``gearbox_cost_usd`` (default
  0, not in eq 4-4) adds a gearbox, DM-DA's "2nd gearbox + 5 %" a second at 105 %; in-wheel "As SM-SA".
* in-wheel motor map (§4.3.1): the base map with the torque axis x ``iwm_torque_scale`` (2.5: 280 -> 700
  Nm) and the speed axis x ``iwm_speed_scale`` (210 / 1100: base speed 54.6 rad/s vs the thesis' 53;
  unit power 38.2 kW vs 38.5 kW); then Fig 2-9 scaling by motor size as for the base map.
* torque split (§4.2.1, §4.2.3): with two driven axles the wheel torque is shared at every time step
  to minimise the electrical power: ``torque_split_steps`` front fractions in [0, 1] (odd: 50/50 is one)
  and the two shares at which a motor reaches its envelope while motoring, the argmin, then 9 points
  around it (never worse than any candidate). Motoring torque over a
  motor's envelope is penalised; braking torque beyond it goes to the friction brake (2-25). Left/right
  motors of an in-wheel axle share their axle's torque equally. The loads while moving are the
  quasi-static model's (``qs.moving_load_w``): DM-DA's second axle drag, the wound-rotor machines' field.

The 0-100 km/h time of every topology is in topology_accel.py.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from . import mass as mass_model
from . import quasi_static as qs
from . import road_load as rl
from .common import design_points
from .cost import motor_cost_usd as _motor_cost_one, pack_cost_usd
from .loss_model import LossModel
from .motor_map import MotorMap
from .params import QUASI_STATIC_SPECS, VEHICLE_CHOICES, VEHICLE_SPECS, check_sm_sa_only, topology_name
from .quasi_static import compiled  # numba, loaded lazily there

TOPOLOGIES = VEHICLE_CHOICES["topology"]
# design variables that only some topologies have (checked by check_design_variables)
TOPOLOGY_VARIABLES = ("gear_ratio", "motor_rear_kw", "gear_ratio_rear", "gear_ratio_2", "shift_speed_m_s",
                      "gear_count")
_PENALTY_W_PER_NM = 1e6  # selection penalty for motoring torque over the envelope
_CHUNK = 20000  # (time x design) rows per split-grid block, bounds memory


@dataclass(frozen=True)
class Topology:
    name: str
    front_motors: int
    rear_motors: int
    geared: bool

    @property
    def two_axles(self) -> bool:
        return self.rear_motors > 0

    @property
    def design_variables(self) -> tuple[str, ...]:
        out = ["motor_kw"] + (["gear_ratio"] if self.geared else []) + ["battery_kwh"]
        if self.two_axles:
            out += ["motor_rear_kw"] + (["gear_ratio_rear"] if self.geared else [])
        if self.name == "SM-SA":
            out += ["gear_ratio_2", "shift_speed_m_s"]  # two-speed (with gear_count = 2)
        return tuple(out)


_SPECS = {"SM-SA": Topology("SM-SA", 1, 0, True), "DM-DA": Topology("DM-DA", 1, 1, True),
          "IWM-SA": Topology("IWM-SA", 2, 0, False), "IWM-DA": Topology("IWM-DA", 2, 2, False)}


def get_topology(name) -> Topology:
    """The topology named ``name``; one-line ValueError listing the allowed names."""
    if isinstance(name, Topology):
        return name
    return _SPECS[topology_name(name)]


def check_design_variables(topology, names) -> None:
    """ValueError if ``names`` holds a topology variable this topology does not have."""
    t = get_topology(topology)
    extra = [n for n in names if n in TOPOLOGY_VARIABLES and n not in t.design_variables and n != "gear_count"]
    if extra:
        why = "direct drive has no gearbox" if not t.geared and extra[0].startswith("gear") else \
            "single axle" if "rear" in extra[0] else "two-speed gearbox is SM-SA only"
        raise ValueError(f"design variable {extra[0]!r} does not exist in topology {t.name} ({why}); "
                         f"its design variables: {', '.join(t.design_variables)}")


# ----------------------------------------------------------------------------- mass and cost

_V, _Q = VEHICLE_SPECS, QUASI_STATIC_SPECS
# the defaults every mass call starts from, built once (a dict over all specs per call was the
# largest cost of a one-point vehicle_mass evaluation)
_MASS_DEFAULTS = {**{k: s.default for k, s in QUASI_STATIC_SPECS.items()}, **mass_model.DEFAULTS}


def motor_unit_mass_kg(topology, motor_kw, motor_rear_kw=None, kg_per_kw=_V["motor_kg_per_kw"].default,
                       base_kg=_V["motor_base_kg"].default,
                       dm_da_transmission_kg=_Q["dm_da_transmission_kg"].default,
                       iwm_mass_factor=_Q["iwm_mass_factor"].default):
    """Motor(s) + transmission change, Table 4-2 (eq 2-18 per motor)."""
    t = get_topology(topology)
    m = t.front_motors * mass_model.motor_mass_kg(motor_kw, kg_per_kw, base_kg)
    if t.two_axles:
        m = m + t.rear_motors * mass_model.motor_mass_kg(_need(motor_rear_kw, "motor_rear_kw", t), kg_per_kw, base_kg)
    if t.name == "DM-DA":
        m = m + dm_da_transmission_kg  # Table 4-1: 30 kg added for the rear axle
    if not t.geared:
        m = m * iwm_mass_factor  # Table 4-1/4-2: 25 % removed
    return m


def vehicle_mass_kg(topology, motor_kw, battery_kwh, params: dict, mass_model_name: str = "ch7",
                    motor_rear_kw=None):
    """Vehicle mass of ``mass_model_name`` with the topology's motor unit (Table 4-2) in place of
    eq 2-18, plus the two-speed gearbox mass (§3.7, 20 kg, SM-SA with gear_count = 2).

    Both mass models are linear in the motor mass: ch7 adds it (factor 1), compounding
    multiplies the change by ``mass_compounding``."""
    p = {**_MASS_DEFAULTS, **params}
    t = get_topology(topology)
    if t.name == "SM-SA":
        two = np.asarray(p["gear_count"]) == 2.0
        return (mass_model.vehicle_mass_kg(motor_kw, battery_kwh, params, mass_model_name)
                + np.where(two, p["two_speed_added_mass_kg"], 0.0))
    check_sm_sa_only(t.name, p)  # as config load does
    ref_kw = np.asarray(p["reference_motor_kw"], float) + 0.0 * np.asarray(motor_kw, float)
    base = mass_model.vehicle_mass_kg(ref_kw, battery_kwh, params, mass_model_name)
    unit = motor_unit_mass_kg(t, motor_kw, motor_rear_kw, p["motor_kg_per_kw"], p["motor_base_kg"],
                              p["dm_da_transmission_kg"], p["iwm_mass_factor"])
    ref_unit = p["motor_kg_per_kw"] * ref_kw + p["motor_base_kg"]
    factor = 1.0 if mass_model_name == "ch7" else p["mass_compounding"]
    return base + factor * (unit - ref_unit)


def motor_cost_usd(topology, motor_kw, motor_rear_kw=None):
    """Table 4-3: eq 2-21 per motor."""
    t = get_topology(topology)
    c = t.front_motors * _motor_cost_one(motor_kw)
    if t.two_axles:
        c = c + t.rear_motors * _motor_cost_one(_need(motor_rear_kw, "motor_rear_kw", t))
    return c


def transmission_cost_usd(topology, gearbox_cost_usd=0.0):
    """Table 4-3 transmission column; eq 4-4 has no gearbox term, so the default is 0."""
    t = get_topology(topology)
    return gearbox_cost_usd * (2.05 if t.name == "DM-DA" else 1.0)  # "2nd gearbox + 5 %"


def powertrain_cost_usd(topology, motor_kw, battery_kwh, motor_rear_kw=None,
                        power_to_energy_ratio=_V["power_to_energy_ratio"].default, gearbox_cost_usd=0.0):
    """Eq 4-4: motors + pack (eqs 4-2, 4-3) + transmission (0 by default)."""
    return (motor_cost_usd(topology, motor_kw, motor_rear_kw) + pack_cost_usd(battery_kwh, power_to_energy_ratio)
            + transmission_cost_usd(topology, gearbox_cost_usd))


def _need(x, name, t):
    if x is None:
        raise ValueError(f"topology {t.name} needs {name}")
    return x


# ----------------------------------------------------------------------------- motor maps

@lru_cache(maxsize=8)
def _in_wheel_map_cached(base: MotorMap, torque_scale: float, speed_scale: float) -> MotorMap:
    return MotorMap(base.speed_rad_s * speed_scale, base.torque_nm * torque_scale, base.efficiency,
                    base.reference_kw * torque_scale * speed_scale, f"{base.name}_in_wheel")


def in_wheel_map(base: MotorMap | None = None, torque_scale: float = _Q["iwm_torque_scale"].default,
                 speed_scale: float = _Q["iwm_speed_scale"].default):
    """§4.3.1: the base map (or loss model) with torque x 2.5 and speed x 210/1100 (unit power 38.2 kW)."""
    if isinstance(base, LossModel):
        return base.scaled(torque_scale, speed_scale)
    return _in_wheel_map_cached(base or qs.default_map(), float(torque_scale), float(speed_scale))


# ----------------------------------------------------------------------------- drive model

@dataclass
class _Axle:
    count: int           # motors on the axle
    kw: np.ndarray       # (N,) power of each motor
    ratio: np.ndarray    # (N,)
    eta: np.ndarray      # (N,) transmission efficiency (1 for direct drive)
    motor_map: MotorMap
    t_peak: np.ndarray   # (N,) peak torque of each motor
    w_lim: float         # rad/s
    regen_share: np.ndarray | float = 1.0  # share of the braking torque the motors may take


def _axles(t: Topology, p, kw_f, kw_r, ig_f, ig_r, base_map) -> list[_Axle]:
    w_lim = p["motor_speed_limit_rpm"] * np.pi / 30.0
    share = np.broadcast_to(p["regen_axle_share"], kw_f.shape)
    if t.geared:
        eta = np.broadcast_to(p["gear_efficiency"], kw_f.shape)
        ax = [_Axle(1, kw_f, ig_f, eta, base_map, p["motor_torque_per_kw"] * kw_f, w_lim, share)]
        if t.two_axles:
            ax.append(_Axle(1, kw_r, ig_r, eta, base_map, p["motor_torque_per_kw"] * kw_r, w_lim, share))
        return ax
    ts, ss = float(np.mean(p["iwm_torque_scale"])), float(np.mean(p["iwm_speed_scale"]))
    if np.ptp(np.atleast_1d(p["iwm_torque_scale"])) or np.ptp(np.atleast_1d(p["iwm_speed_scale"])):
        raise ValueError("iwm_torque_scale and iwm_speed_scale must be the same for every design point")
    m = in_wheel_map(base_map, ts, ss)
    one, tpk = np.ones_like(kw_f), p["motor_torque_per_kw"] / ss  # 700 Nm / 38.2 kW per unit motor
    ax = [_Axle(t.front_motors, kw_f, one, one, m, tpk * kw_f, w_lim * ss, share)]
    if t.two_axles:
        ax.append(_Axle(t.rear_motors, kw_r, one, one, m, tpk * kw_r, w_lim * ss, share))
    return ax


def _t_max(ax: _Axle, w):
    """Per-motor envelope at motor speed ``w``: peak torque, constant power, 0 beyond w_lim."""
    return np.where(w <= ax.w_lim, np.minimum(ax.t_peak, ax.kw * 1e3 / np.maximum(w, 1e-9)), 0.0)


def _axle_power(ax: _Axle, tw, w, tmax, driving, allowed):
    """Electrical power of an axle carrying wheel torque ``tw`` and its motoring overload (N m)."""
    tm = np.where(driving, tw / (ax.count * ax.ratio * ax.eta), tw * ax.eta / (ax.count * ax.ratio))  # 2-5
    over = np.where(driving, np.maximum(tm - tmax, 0.0), 0.0)
    tm = np.where(driving, tm, np.where(allowed, np.maximum(tm * ax.regen_share, -tmax), 0.0))  # 2-25, rules 2-3
    return ax.count * ax.motor_map.electrical_power_w(tm, w, ax.kw), over, tm


def best_split(axles, tw, v, r_w, driving, allowed, steps: int = 11):
    """Front share of wheel torque minimising electrical power per (time, design) row.

    ``tw``, ``driving``, ``allowed``: (K, N); ``v``: (K, 1). Returns (share, power_w,
    overload_nm), each (K, N). Vectorised over a (rows, N, grid) block."""
    fr, rr = axles
    grid = np.linspace(0.0, 1.0, int(steps))
    delta = grid[1] - grid[0]
    fine = np.linspace(-delta, delta, 9)
    K, N = tw.shape
    share = np.empty((K, N))
    power = np.empty((K, N))
    over = np.empty((K, N))
    rows = max(1, _CHUNK // max(N, 1))
    for k0 in range(0, K, rows):
        sl = slice(k0, k0 + rows)
        vv = v[sl][..., None]
        twk, dk, ak = tw[sl][..., None], driving[sl][..., None], allowed[sl][..., None]
        wf = vv / r_w * fr.ratio[None, :, None]
        wr = vv / r_w * rr.ratio[None, :, None]
        tmf, tmr = _t_max(_bcast(fr), wf), _t_max(_bcast(rr), wr)

        def cost(s):
            pf, of, _ = _axle_power(_bcast(fr), twk * s, wf, tmf, dk, ak)
            pr, orr, _ = _axle_power(_bcast(rr), twk * (1.0 - s), wr, tmr, dk, ak)
            return pf + pr, of + orr

        # candidates: the grid, then the shares at which the front and the rear motor reach their
        # envelope while motoring (the optimum often sits there; without them the best share jumped
        # from one end to the other as an envelope crossed the demand, and the energy with it)
        envelope = _envelope_shares(_bcast(fr), _bcast(rr), twk, tmf, tmr, dk)
        cand = np.concatenate([np.broadcast_to(grid, twk.shape[:2] + grid.shape), envelope], axis=2)
        p, o = cost(cand)
        j = np.argmin(p + _PENALTY_W_PER_NM * o, axis=2)
        s0 = np.take_along_axis(cand, j[..., None], 2)[..., 0]
        s2 = np.clip(s0[..., None] + fine, 0.0, 1.0)  # fine[4] == 0: the coarse argmin stays a candidate
        p2, o2 = cost(s2)
        j2 = np.argmin(p2 + _PENALTY_W_PER_NM * o2, axis=2)[..., None]
        share[sl] = np.take_along_axis(s2, j2, 2)[..., 0]
        power[sl] = np.take_along_axis(p2, j2, 2)[..., 0]
        over[sl] = np.take_along_axis(o2, j2, 2)[..., 0]
    return share, power, over


def _envelope_shares(fr: _Axle, rr: _Axle, twk, tmf, tmr, driving) -> np.ndarray:
    """(..., 2): the front shares at which the front motor, then the rear one, carries its envelope
    torque (2-5) of positive wheel torque ``twk``, within [0, 1]; 1 and 0 (grid ends) otherwise.
    ``fr``, ``rr`` as ``_bcast`` shapes them."""
    pos = driving & (twk > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        front = np.where(pos, np.minimum(np.maximum(tmf * (fr.count * fr.ratio * fr.eta) / twk, 0.0), 1.0), 1.0)
        rear = np.where(pos, np.minimum(np.maximum(1.0 - tmr * (rr.count * rr.ratio * rr.eta) / twk, 0.0), 1.0), 0.0)
    return np.concatenate([front, rear], axis=-1)


def _bcast(ax: _Axle) -> _Axle:
    """The axle with its (N,) arrays shaped (1, N, 1) for (time, N, grid) blocks."""
    f = (lambda a: np.asarray(a, float)[None, :, None])
    return _Axle(ax.count, f(ax.kw), f(ax.ratio), f(ax.eta), ax.motor_map, f(ax.t_peak), ax.w_lim,
                 f(np.broadcast_to(ax.regen_share, np.shape(ax.kw))))


def _prepare(params, topology, vehicle_mass_kg, motor_kw, battery_kwh, gear_ratio, motor_rear_kw, gear_ratio_rear):
    t = get_topology(topology)
    arrays = {"vehicle_mass_kg": vehicle_mass_kg, "motor_kw": motor_kw, "battery_kwh": battery_kwh}
    if t.geared:
        arrays["gear_ratio"] = _need(gear_ratio, "gear_ratio", t)
    if t.two_axles:
        arrays["motor_rear_kw"] = _need(motor_rear_kw, "motor_rear_kw", t)
        if t.geared:
            arrays["gear_ratio_rear"] = _need(gear_ratio_rear, "gear_ratio_rear", t)
    arrays = {k: design_points(k, v, real=True) for k, v in arrays.items()}
    n = max([a.shape[0] for a in arrays.values()]
            + [np.size(params[k]) for k in QUASI_STATIC_SPECS if params and k in params])
    arrays = {k: np.broadcast_to(a, (n,)).copy() if a.shape[0] in (1, n) else a for k, a in arrays.items()}
    m, ig, kw, p = qs.inputs(params, arrays["vehicle_mass_kg"], arrays.get("gear_ratio", np.ones(n)),
                              arrays["motor_kw"], arrays["battery_kwh"])
    check_sm_sa_only(t.name, p)  # as config load does
    return t, m, ig, kw, p, arrays.get("motor_rear_kw"), arrays.get("gear_ratio_rear")


def _moving_load_w(t: Topology, p, v, axles):
    """``qs.moving_load_w`` while moving, on the topology's total rated power (DM-DA: two axles)."""
    return np.where(v > 0, qs.moving_load_w(p, sum(a.count * a.kw for a in axles), 1.0 + (t.name == "DM-DA")), 0.0)


def _demand(resampled, t: Topology, p, m, ig, kw, kw_r, ig_r, base_map):
    """Per-step battery demand of a topology, as the quasi-static model's ``Demand``."""
    if t.name == "SM-SA":
        return qs.demand(resampled, p, m, ig, kw, base_map)
    dt, v_bar, a_bar = qs.cycle_steps(resampled)  # 6-50, 6-51
    g, r_w = p["gravity_m_s2"], p["wheel_radius_m"]
    force = rl.road_load_n(p, v_bar, m) + m * a_bar  # 2-3 (or the coast-down road load)
    tw = force * r_w  # 2-1 (all driven wheels)
    driving = force >= 0
    allowed = (~driving) & (v_bar >= p["regen_min_speed_m_s"]) & (a_bar >= -p["regen_max_decel_g"] * g)
    axles = _axles(t, p, kw, kw_r, ig, ig_r, base_map)
    K, N = tw.shape
    if t.two_axles:
        share, p_el, _ = best_split(axles, tw, v_bar, r_w, driving, allowed, int(np.max(p["torque_split_steps"])))
    else:
        ax = axles[0]
        w = v_bar / r_w * ax.ratio
        p_el, _, _ = _axle_power(ax, tw, w, _t_max(ax, w), driving, allowed)
        share = np.ones((K, N))
    p_el = p_el + _moving_load_w(t, p, v_bar, axles)
    cap = sum(a.count * _t_max(a, v_bar / r_w * a.ratio) * a.ratio * a.eta for a in axles)  # wheel N m
    margin = np.where(driving, cap - tw, np.inf).min(axis=0)
    w_max = np.max([(v_bar.max() / r_w * a.ratio) for a in axles], axis=0)
    steps = {"speed_m_s": v_bar, "accel_m_s2": a_bar, "wheel_torque_nm": tw, "front_share": share,
             "motor_power_w": p_el}
    steps = {k: np.broadcast_to(x, (K, N)) for k, x in steps.items()}
    return qs.Demand(dt, np.where(p_el > 0, p_el, 0.0), np.where(p_el > 0, 0.0, p_el),  # drawn / offered
                      float(np.sum(v_bar[:, 0] * dt[:, 0])), np.broadcast_to(w_max, (N,)), margin,
                      axles[0].w_lim + 0.0 * kw, steps)


def _fast_demand(resampled, t: Topology, p, m, ig, kw, kw_r, ig_r, base_map) -> qs.FastDemand:
    """``_demand`` in the compiled per-design loop (compiled.drive_demand; SM-SA: qs.fast_demand)."""
    if t.name == "SM-SA":
        return qs.fast_demand(resampled, p, m, ig, kw, base_map)
    dt, v_bar, a_bar = qs.cycle_steps(resampled)  # 6-50, 6-51
    n = m.shape[0]
    axles = _axles(t, p, kw, kw_r, ig, ig_r, base_map)
    cols = {"mass": m, **qs.road_columns(p), "r_w": p["wheel_radius_m"], "regen_min_m_s": p["regen_min_speed_m_s"],
            "decel_min": -p["regen_max_decel_g"] * p["gravity_m_s2"], "regen_share": p["regen_axle_share"],
            "axles": 1.0}
    for a, tail in zip(axles, ("", "_r")):
        cols.update({"ratio" + tail: a.ratio, "eta" + tail: a.eta, "kw" + tail: a.kw, "t_peak" + tail: a.t_peak,
                     "scale" + tail: a.motor_map.reference_kw / a.kw, "w_lim" + tail: a.w_lim,
                     "count" + tail: float(a.count)})
    grid = np.linspace(0.0, 1.0, int(np.max(p["torque_split_steps"])))
    fine = np.linspace(-(grid[1] - grid[0]), grid[1] - grid[0], 9)
    v_pair, a_pair, step_pair = qs.step_pairs(v_bar, a_bar)
    power, speed_max, margin = compiled.drive_demand(v_pair, a_pair, compiled.table(compiled.COLUMNS, n, cols), False,
                                                     t.two_axles, grid, fine, *qs.motor_arrays(axles[0].motor_map))
    power = power + np.transpose(_moving_load_w(t, p, v_pair[:, None], axles))  # (N, U) as the power
    return qs.FastDemand(np.array(dt[:, 0]), power, step_pair, float(np.sum(v_bar[:, 0] * dt[:, 0])), speed_max,
                         margin, axles[0].w_lim + 0.0 * kw)


def simulate(resampled, params, topology, vehicle_mass_kg, motor_kw, battery_kwh=qs.DEFAULT_BATTERY_KWH, gear_ratio=None,
             motor_rear_kw=None, gear_ratio_rear=None, *, motor_map: MotorMap | None = None, reference: bool = False):
    """One pass over the cycle (``qs.QuasiStaticResult``; SM-SA is exactly ``qs.simulate``).

    For two-axle and in-wheel topologies ``torque_margin_nm`` is at the wheels (sum of the
    motors' envelopes minus the demand) and ``motor_speed_max_rad_s`` is the fastest motor.
    ``reference``: the numpy passes instead of the compiled loops (same result to 1e-12)."""
    t, m, ig, kw, p, kw_r, ig_r = _prepare(params, topology, vehicle_mass_kg, motor_kw, battery_kwh, gear_ratio,
                                           motor_rear_kw, gear_ratio_rear)
    model = qs.drive_model(p, motor_map)
    if reference:
        d = _demand(resampled, t, p, m, ig, kw, kw_r, ig_r, model)
        return qs.integrate_energy(d, p, m.shape[0])
    d = _fast_demand(resampled, t, p, m, ig, kw, kw_r, ig_r, model)
    return qs.fast_energy(d, p, m.shape[0])


def energy_wh_per_km(resampled, params, topology, vehicle_mass_kg, motor_kw, battery_kwh=qs.DEFAULT_BATTERY_KWH, gear_ratio=None,
                     motor_rear_kw=None, gear_ratio_rear=None, *, motor_map: MotorMap | None = None):
    """Battery-terminal energy per km (2-16, 2-17) of a topology, shape (N,)."""
    return simulate(resampled, params, topology, vehicle_mass_kg, motor_kw, battery_kwh, gear_ratio,
                    motor_rear_kw, gear_ratio_rear, motor_map=motor_map).energy_wh_per_km


def range_by_repeated_cycle_km(resampled, params, topology, vehicle_mass_kg, motor_kw, battery_kwh,
                               gear_ratio=None, motor_rear_kw=None, gear_ratio_rear=None, *,
                               motor_map: MotorMap | None = None, max_repeats: int = 200, reference: bool = False):
    """Chapter-3 range (repeat the cycle from 100 % to 5 % SOC, §3.5.3) of a topology, km (N,);
    the demand once, then only the battery through the repeats."""
    t, m, ig, kw, p, kw_r, ig_r = _prepare(params, topology, vehicle_mass_kg, motor_kw, battery_kwh, gear_ratio,
                                           motor_rear_kw, gear_ratio_rear)
    step_m = qs.step_distances_m(resampled)
    model = qs.drive_model(p, motor_map)
    if reference:
        d = _demand(resampled, t, p, m, ig, kw, kw_r, ig_r, model)
        return qs.integrate_range(d, p, m.shape[0], step_m, max_repeats)
    d = _fast_demand(resampled, t, p, m, ig, kw, kw_r, ig_r, model)
    return qs.fast_range(d, p, m.shape[0], step_m, max_repeats)


def operating_points(resampled, params, topology, vehicle_mass_kg, motor_kw, battery_kwh=qs.DEFAULT_BATTERY_KWH, gear_ratio=None,
                     motor_rear_kw=None, gear_ratio_rear=None, *, motor_map: MotorMap | None = None) -> dict:
    """Per-step (K, N) arrays: speed, acceleration, wheel torque, front share, motor power."""
    t, m, ig, kw, p, kw_r, ig_r = _prepare(params, topology, vehicle_mass_kg, motor_kw, battery_kwh, gear_ratio,
                                           motor_rear_kw, gear_ratio_rear)
    return _demand(resampled, t, p, m, ig, kw, kw_r, ig_r, qs.drive_model(p, motor_map)).steps
