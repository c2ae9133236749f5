"""Quasi-static backward model (thesis chapters 2-3, discretised as eqs 6-49..6-56).

On each cycle step of length h the vehicle runs at the mean speed v_bar and the step's
acceleration a_bar (6-50, 6-51). Per step, vectorised over time x design points:

    F   = 1/2 rho C_dA v_bar^2 + C_r M g + M a_bar           (2-3 / 6-53, flat road; road_load.py)
    w_w = v_bar / r_w,  T_w = F r_w                          (2-1, 2-2)
    i_g = gear_ratio, or gear_ratio_2 at v_bar >= shift speed (2-6, two-speed)
    w_m = w_w i_g,  T_m = T_w / (i_g eta_g) driving          (2-4, 2-5)
                    T_m = T_w eta_g / i_g braking
    P_m = T_m w_m / eta_m (driving), T_m w_m eta_m (regen)   (2-7, 2-8 motor map)
    or, with ``motor_loss_model = 1``, P_m = T_m w_m + L(T_m, w_m, P) on ``driven_axles`` equal
    machines (loss_model.py, the fleet-calibrated set epa2022_quasi_static)

The road load is road_load.py's, as in every model: it acts while the vehicle moves, so a
standing step has no wheel force (it never cost energy: the motor does no work at zero speed).

Regenerative braking (§2.3.4): the motor brakes with max(share T_required, -T_max(w)) (2-25;
``regen_axle_share``, 1 in the thesis),
none below 10 km/h, none beyond 0.7 g deceleration, none above 90 % SOC, and the charge
current is capped at 2C; the rest is friction braking. Then the battery steps in time,
vectorised over points: V_BT from P (2-13, 2-14), I = P / V_BT (2-11), SOC (2-9, 2-10).
Energy (2-16, 2-17) is the sum of terminal power x h over the cycle, per km.

Two-speed gearbox (§3.3.2): ``gear_count = 2`` uses ``gear_ratio_2`` above
``shift_speed_m_s`` (eq 2-6; ``shift_strategy = 1`` instead picks, per step, the gear with the
lower electrical power that the envelope allows) and applies the thesis penalty: efficiency -2 points and +20 kg
(``two_speed_added_mass_kg``; set it to 0 if the mass discipline already adds it).

Speed: ``simulate`` and ``range_by_repeated_cycle_km`` run the compiled per-design loops of
compiled.py and compiled_battery.py (``fast_demand``, ``fast_energy``, ``fast_range``);
``reference=True`` runs the plain numpy passes (``demand``, ``integrate_energy``,
``integrate_range``) that the tests hold them to.

Feasibility (§3.5.3) is reported, not enforced: traction torque within the envelope,
motor speed within the limit, discharge current <= 5C and power within the battery's
ocv^2/4R. The energy of an infeasible design is still finite (the map is clipped). The SOC has
no floor: a pack too small for the cycle goes below 0 (its OCV and resistance stay at their 0 %
values) and a demand over ocv^2/4R is delivered only up to it, so such a pack's energy per km
leaves out what it did not deliver; ``soc_min`` and ``battery_power_margin_kw`` measure both.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from . import battery as bt
from . import road_load as rl
from .common import LazyModule, batch_size, design_points, resolve_params
from .loss_model import LossModel
from .motor_map import DEFAULT_MAP_CSV, MotorMap, load_motor_map_csv
from .params import QUASI_STATIC_SPECS, VEHICLE_SPECS

compiled = LazyModule(f"{__package__}.compiled")  # numba, loaded when a compiled loop first runs
battery_loops = LazyModule(f"{__package__}.compiled_battery")

PARAM_SPECS = QUASI_STATIC_SPECS
DEFAULT_BATTERY_KWH = VEHICLE_SPECS["reference_battery_kwh"].default  # Leaf, 24 kWh


@lru_cache(maxsize=1)
def default_map() -> MotorMap:
    """The packaged default map (bev_mdo/data/motor_map_default.csv)."""
    return load_motor_map_csv(DEFAULT_MAP_CSV)


def drive_model(p, motor_map: MotorMap | None = None) -> MotorMap | LossModel:
    """The motor of a batch: ``motor_map`` when given, else the loss model (loss_model.py) when the
    parameters ask for it (``motor_loss_model = 1``), else the packaged map."""
    if motor_map is not None:
        return motor_map
    flag = np.atleast_1d(np.asarray(p["motor_loss_model"], float))
    if np.ptp(flag):  # 0 or 1 (checked with the parameters)
        raise ValueError("motor_loss_model must be 0 (map) or 1 (loss model), the same for every design point")
    return LossModel.from_params(p) if flag[0] == 1.0 else default_map()


@dataclass
class QuasiStaticResult:
    """One pass over a cycle (or repeated cycles for range), arrays of shape (N,)."""

    energy_wh_per_km: np.ndarray
    distance_m: float
    soc_end: np.ndarray
    motor_speed_max_rad_s: np.ndarray
    torque_margin_nm: np.ndarray  # min over the cycle of T_max(w) - T_m when driving
    torque_ok: np.ndarray
    speed_ok: np.ndarray
    regen_wh_per_km: np.ndarray  # energy returned to the battery terminals (>= 0)
    soc_min: np.ndarray  # lowest SOC over the cycle, the start included (< 0: the pack ran out)
    battery_power_margin_kw: np.ndarray  # min over the drawing steps of ocv^2/4R - drive demand (inf: none)
    battery_current_margin: np.ndarray  # min over the drawing steps of 1 - current / discharge limit (inf: none)

    @property
    def current_ok(self) -> np.ndarray:
        """The current never above the pack's discharge limit (``discharge_c_max`` x capacity)."""
        return self.battery_current_margin >= -1e-12

    @property
    def power_ok(self) -> np.ndarray:
        """The drive demand never above the pack's maximum power ocv^2/4R (2-15)."""
        return self.battery_power_margin_kw >= 0

    @property
    def feasible(self) -> np.ndarray:
        return self.torque_ok & self.speed_ok & self.current_ok & self.power_ok


@dataclass
class Demand:
    dt: np.ndarray  # (K, 1)
    p_drive_w: np.ndarray  # (K, N) electrical power when driving (>= 0), else 0
    p_regen_w: np.ndarray  # (K, N) regenerative electrical power allowed by the speed/decel/torque rules (<= 0)
    distance_m: float
    speed_max: np.ndarray
    torque_margin: np.ndarray
    speed_limit: np.ndarray
    steps: dict  # per-step (K, N) operating points, see operating_points()


def inputs(params, vehicle_mass_kg, gear_ratio, motor_kw, battery_kwh=DEFAULT_BATTERY_KWH):
    """Checked design points broadcast to one length N, and the resolved parameters (real, (N,)
    or scalar): (mass, gear ratio, motor kW, params with ``battery_kwh``). Also used by topology.py."""
    m = design_points("vehicle_mass_kg", vehicle_mass_kg, real=True)
    ig = design_points("gear_ratio", gear_ratio, real=True)
    kw = design_points("motor_kw", motor_kw, real=True)
    kwh = design_points("battery_kwh", battery_kwh, real=True)
    n = batch_size(params, PARAM_SPECS, vehicle_mass_kg=m, gear_ratio=ig, motor_kw=kw, battery_kwh=kwh)
    m, ig, kw, kwh = (np.broadcast_to(a, (n,)) for a in (m, ig, kw, kwh))
    p = resolve_params(params, PARAM_SPECS, n, real=True)
    p["battery_kwh"] = kwh
    p.update(rl.checked(params))
    return m, ig, kw, p


def cycle_steps(cycle):
    """(dt, v_bar, a_bar) of every step as (K, 1) columns: step length, mean speed (6-50) and
    acceleration (6-51). ValueError for a cycle that does not move. Also used by topology.py."""
    t = np.asarray(cycle.time_s, float)
    v = np.asarray(cycle.speed_m_s, float)
    dt = np.diff(t)[:, None]
    v_bar = 0.5 * (v[1:] + v[:-1])[:, None]  # 6-50
    if not np.sum(v_bar[:, 0] * dt[:, 0]) > 0:
        raise ValueError(f"drive cycle {getattr(cycle, 'name', '?')} has zero distance")
    return dt, v_bar, np.diff(v)[:, None] / dt  # 6-51


def moving_load_w(p, kw, axles) -> np.ndarray:
    """Electrical load of the loss model while the car moves, per design (W): a second driven axle's
    drag, and the rotor field of wound-rotor machines (EESM: a permanent-magnet or induction machine
    has no such term; the fleet's EESM cars fit it at about 1 W per kW, docs/validation.md)."""
    return ((axles - 1.0) * p["second_axle_drag_w"]
            + p["excitation_loss_w_per_kw"] * p["wound_rotor_machine_share"] * kw)


def demand(cycle, p, m, ig, kw, motor_map: MotorMap) -> Demand:
    """Per-step battery demand of the single-motor drive (eqs 2-1..2-8, 6-50/6-51, §2.3.4 rules 1-3)."""
    dt, v_bar, a_bar = cycle_steps(cycle)
    two = p["gear_count"] == 2.0
    mass = m + np.where(two, p["two_speed_added_mass_kg"], 0.0)
    eta_g = p["gear_efficiency"] - np.where(two, p["two_speed_efficiency_loss"], 0.0)
    if np.any(eta_g <= 0):
        raise ValueError("gear_efficiency minus two_speed_efficiency_loss must stay > 0")
    g = p["gravity_m_s2"]
    force = rl.road_load_n(p, v_bar, mass) + mass * a_bar  # 2-3, 6-53 (or the coast-down road load)
    r_w = p["wheel_radius_m"]
    ratio = np.where(two & (v_bar >= p["shift_speed_m_s"]), p["gear_ratio_2"], ig)  # 2-6
    t_w = force * r_w  # 2-1
    driving = force >= 0
    share = p["regen_axle_share"]  # the rest of the braking force is friction
    loss_model = isinstance(motor_map, LossModel)
    axles = p["driven_axles"]
    w_lim = p["motor_speed_limit_rpm"] * np.pi / 30.0
    t_pk = p["motor_torque_per_kw"] * kw
    allowed = (~driving) & (v_bar >= p["regen_min_speed_m_s"]) & (a_bar >= -p["regen_max_decel_g"] * g)

    def at(ratio):
        w_m = v_bar / r_w * ratio  # 2-2, 2-4
        t_drive = np.where(driving, t_w / (ratio * eta_g), 0.0)  # 2-5
        t_brake = np.where(driving, 0.0, t_w * eta_g / ratio)
        t_max = np.where(w_m <= w_lim, np.minimum(t_pk, kw * 1e3 / np.maximum(w_m, 1e-9)), 0.0)
        t_regen = np.where(allowed, np.maximum(t_brake * share, -t_max), 0.0)  # 2-25, §2.3.4 rules 2-3
        if loss_model:  # driven_axles equal machines of P / n sharing the torque, + the loads while moving
            # (with the map two machines of P / 2 are one of P, Fig 2-9: driven_axles changes nothing)
            p_el = axles * motor_map.electrical_power_w((t_drive + t_regen) / axles, w_m, kw / axles)
        else:
            p_el = motor_map.electrical_power_w(t_drive + t_regen, w_m, kw)  # 2-7 (one lookup)
        p_el = p_el + np.where(v_bar > 0, moving_load_w(p, kw, axles if loss_model else 1.0), 0.0)
        return w_m, t_drive, t_brake, t_max, t_regen, p_el

    eff = two & (p["shift_strategy"] == 1.0)
    if np.any(eff):  # per step the gear of least electrical power that the envelope allows
        cost = []
        for r in (ig, p["gear_ratio_2"]):
            w_m, t_drive, _, t_max, _, p_el = at(np.broadcast_to(r, kw.shape))
            cost.append(np.where((w_m <= w_lim) & (t_drive <= t_max), p_el, np.inf))
        pick2 = (cost[1] < cost[0]) | (np.isinf(cost[0]) & np.isinf(cost[1]) & (ratio != ig))
        ratio = np.where(eff, np.where(pick2, p["gear_ratio_2"], ig), ratio)
    w_m, t_drive, t_brake, t_max, t_regen, p_el = at(ratio)
    margin = np.where(driving, t_max - t_drive, np.inf).min(axis=0)
    shape = p_el.shape
    steps = {"speed_m_s": v_bar, "accel_m_s2": a_bar, "gear_ratio": ratio, "motor_speed_rad_s": w_m,
             "motor_torque_nm": t_drive + t_regen, "motor_torque_max_nm": t_max, "wheel_force_n": force,
             "friction_brake_torque_nm": t_brake - t_regen, "motor_power_w": p_el}
    steps = {k: np.broadcast_to(x, shape) for k, x in steps.items()}
    return Demand(dt, np.where(p_el > 0, p_el, 0.0), np.where(p_el > 0, 0.0, p_el),  # drawn / offered
                   float(np.sum(v_bar[:, 0] * dt[:, 0])), np.broadcast_to(w_m.max(axis=0), kw.shape),
                   margin, w_lim + 0.0 * kw, steps)


@dataclass
class FastDemand:
    """The compiled demand: one signed battery-side power (>= 0 motoring, < 0 offered by
    regeneration) per distinct (mean speed, acceleration) of the cycle, (N, U), step k's being
    column ``step_pair[k]``, with the per-design outputs of ``Demand``."""

    dt: np.ndarray  # (K,)
    power_w: np.ndarray  # (N, U)
    step_pair: np.ndarray  # (K,) column of power_w that is step k's
    distance_m: float
    speed_max: np.ndarray
    torque_margin: np.ndarray
    speed_limit: np.ndarray


def step_pairs(v_bar, a_bar) -> tuple:
    """The distinct (mean speed, acceleration) pairs of a cycle's steps and each step's pair:
    (v (U,), a (U,), pair of step k (K,)). A step's demand depends on its pair alone (eqs
    2-1..2-8, rules 1-3), so the compiled loops compute it once per pair (a 1 s Artemis cycle
    has 2,279 pairs in 5,215 steps, the NEDC 179 in 1,180). Pairs are told apart by their bits."""
    va = np.stack([np.asarray(v_bar, float).reshape(-1), np.asarray(a_bar, float).reshape(-1)], axis=1)
    _, first, pair = np.unique(va.view(np.int64), axis=0, return_index=True, return_inverse=True)
    return np.ascontiguousarray(va[first, 0]), np.ascontiguousarray(va[first, 1]), pair.reshape(-1).astype(np.int64)


def motor_arrays(model) -> tuple:
    """(map tuple, loss tuple) of a map or a loss model as ``compiled.drive_demand`` takes them (a loss
    model comes with the default map's tuple, which it does not read)."""
    if isinstance(model, LossModel):
        return map_arrays(default_map()), compiled.loss_tuple(model.as_tuple())
    return map_arrays(model), compiled.loss_tuple()


def map_arrays(motor_map: MotorMap) -> tuple:
    """The motor map as the compiled loops take it (compiled.map_tuple), built once per map."""
    key = id(motor_map)
    if key not in _MAP_ARRAYS or _MAP_ARRAYS[key][0] is not motor_map:
        if len(_MAP_ARRAYS) > 16:
            _MAP_ARRAYS.clear()
        _MAP_ARRAYS[key] = (motor_map, compiled.map_tuple(
            motor_map.speed_rad_s, motor_map.torque_nm, motor_map.efficiency, motor_map.reference_kw,
            motor_map.has_regen_rows))
    return _MAP_ARRAYS[key][1]


_MAP_ARRAYS: dict = {}  # id -> (map, its compiled form); the map is kept so its id is not reused


def road_columns(p) -> dict:
    """Road-load coefficients (A0, A1, B, C) of road_load.coefficients, named as compiled.COLUMNS."""
    return dict(zip(("a0", "a1", "b", "c"), rl.coefficients(p)))


def fast_demand(cycle, p, m, ig, kw, motor_map: MotorMap) -> FastDemand:
    """``demand`` in the compiled per-design loop (compiled.drive_demand)."""
    dt, v_bar, a_bar = cycle_steps(cycle)
    n = m.shape[0]
    two = np.broadcast_to(p["gear_count"] == 2.0, (n,))
    eta_g = p["gear_efficiency"] - np.where(two, p["two_speed_efficiency_loss"], 0.0)
    if np.any(eta_g <= 0):
        raise ValueError("gear_efficiency minus two_speed_efficiency_loss must stay > 0")
    w_lim = p["motor_speed_limit_rpm"] * np.pi / 30.0
    lossy = isinstance(motor_map, LossModel)
    axles = p["driven_axles"]
    cols = compiled.table(compiled.COLUMNS, n, dict(
        mass=m + np.where(two, p["two_speed_added_mass_kg"], 0.0), **road_columns(p), r_w=p["wheel_radius_m"],
        regen_min_m_s=p["regen_min_speed_m_s"], decel_min=-p["regen_max_decel_g"] * p["gravity_m_s2"],
        ratio=ig, eta=eta_g, kw=kw, t_peak=p["motor_torque_per_kw"] * kw,
        scale=motor_map.reference_kw / (kw / axles) if lossy else motor_map.reference_kw / kw,  # as demand()
        w_lim=w_lim, count=1.0, ratio_2=p["gear_ratio_2"], shift_m_s=p["shift_speed_m_s"], two_speed=two,
        best_gear=two & (p["shift_strategy"] == 1.0), regen_share=p["regen_axle_share"],
        axles=axles if lossy else 1.0, moving_load_w=moving_load_w(p, kw, axles if lossy else 1.0)))
    v_pair, a_pair, step_pair = step_pairs(v_bar, a_bar)
    power, speed_max, margin = compiled.drive_demand(v_pair, a_pair, cols, True, False, np.zeros(1), np.zeros(1),
                                                     *motor_arrays(motor_map))
    return FastDemand(np.array(dt[:, 0]), power, step_pair, float(np.sum(v_bar[:, 0] * dt[:, 0])), speed_max, margin,
                      w_lim + 0.0 * kw)


def battery_table(p, n: int) -> tuple:
    """The per-design battery table (compiled_battery.BATTERY_COLUMNS) from the same ``_Battery`` the
    reference loop uses, and the cell's tables."""
    b = _Battery(p, n)
    cell = b.pack.cell
    cols = compiled.table(battery_loops.BATTERY_COLUMNS, n, dict(
        cells_series=b.pack.cells_series, cells_parallel=b.pack.cells_parallel, capacity_c=b.q_c,
        charge_current_max_a=b.i_chg_max, regen_max_soc=b.soc_max_regen, initial_soc=p["initial_soc"],
        discharge_current_max_a=b.i_dis_max, loss_weight=b.w_loss, final_soc=p["final_soc"]))
    return cols, battery_loops.cell_tables(cell.soc, cell.ocv_v, cell.r_discharge_ohm, cell.r_charge_ohm)


def fast_energy(d: FastDemand, p, n: int) -> QuasiStaticResult:
    """``integrate_energy`` in the compiled per-design loop (compiled_battery.battery_energy)."""
    energy, regen, soc, soc_min, room_w, room_i = battery_loops.battery_energy(
        d.power_w, d.step_pair, d.dt, *battery_table(p, n))
    km = d.distance_m / 1e3
    return QuasiStaticResult(energy / 3600.0 / km, d.distance_m, soc, d.speed_max, d.torque_margin,
                             d.torque_margin >= -1e-9, d.speed_max <= d.speed_limit,
                             regen / 3600.0 / km, soc_min, room_w / 1e3, room_i)


def fast_range(d: FastDemand, p, n: int, step_m: np.ndarray, max_repeats: int = 200) -> np.ndarray:
    """``integrate_range`` in the compiled per-design loop (compiled_battery.battery_range_m), km (N,)."""
    return battery_loops.battery_range_m(d.power_w, d.step_pair, d.dt, np.array(step_m, dtype=float), int(max_repeats),
                                    *battery_table(p, n)) / 1e3


def operating_points(resampled, params, vehicle_mass_kg, gear_ratio, motor_kw, *,
                     motor_map: MotorMap | None = None) -> dict[str, np.ndarray]:
    """Per-step (K, N) operating points before the battery: speed, acceleration, gear ratio,
    motor speed/torque (regen torque after rules 1-3 of §2.3.4), envelope, wheel force,
    friction-brake torque (at the motor shaft, <= 0) and motor electrical power."""
    m, ig, kw, p = inputs(params, vehicle_mass_kg, gear_ratio, motor_kw)
    return demand(resampled, p, m, ig, kw, drive_model(p, motor_map)).steps


class _Battery:
    """Per-point battery state stepping in time (2-9..2-15) with the §2.3.4 charge rules."""

    def __init__(self, p, n):
        self.pack = bt.pack_for_energy(p["battery_kwh"], p["cells_series"])
        cap_ah = self.pack.capacity_ah
        self.q_c = self.pack.capacity_c
        self.i_chg_max = p["charge_c_max"] * cap_ah
        self.i_dis_max = p["discharge_c_max"] * cap_ah
        self.soc_max_regen = p["regen_max_soc"]
        self.w_loss = p["battery_loss_weight"]
        self.power_room_w = np.full(n, np.inf)  # min of p_max - p_drive over the steps that draw
        self.current_room = np.full(n, np.inf)  # min of 1 - i / i_dis_max over the steps that draw

    def step(self, soc, p_drive, p_regen, dt):
        """Terminal power, energy drawn (J) and the new SOC after one step of ``dt`` s."""
        p_regen = np.where(soc > self.soc_max_regen, 0.0, p_regen)  # rule 4: SOC > 90 %
        charging = p_regen < 0
        voc = self.pack.ocv(soc)
        r = self.pack.resistance(soc, charging)
        p_chg_lim = bt.power_at_current_w(-self.i_chg_max, voc, r)  # 2C charge cap
        p_max = bt.max_discharge_power_w(voc, r)
        self.power_room_w = np.minimum(self.power_room_w, np.where(p_drive > 0, p_max - p_drive, np.inf))
        power = np.minimum(p_drive, p_max) + np.maximum(p_regen, p_chg_lim)
        i = bt.terminal_current_a(power, voc, r)  # 2-11..2-14
        self.current_room = np.minimum(self.current_room, np.where(p_drive > 0, 1.0 - i / self.i_dis_max, np.inf))
        e = (power + self.w_loss * i * i * r) * dt  # 2-17 (+ optional internal loss)
        return power, e, bt.soc_after(soc, i, dt, self.q_c)


def simulate(resampled, params, vehicle_mass_kg, gear_ratio, motor_kw, battery_kwh=DEFAULT_BATTERY_KWH,
             *, motor_map: MotorMap | None = None, reference: bool = False) -> QuasiStaticResult:
    """One pass over the cycle from ``initial_soc``; everything per design point (N,).
    ``reference``: the numpy passes instead of the compiled loops (same result to 1e-12)."""
    m, ig, kw, p = inputs(params, vehicle_mass_kg, gear_ratio, motor_kw, battery_kwh)
    model = drive_model(p, motor_map)
    if reference:
        return integrate_energy(demand(resampled, p, m, ig, kw, model), p, m.shape[0])
    return fast_energy(fast_demand(resampled, p, m, ig, kw, model), p, m.shape[0])



def integrate_energy(d: Demand, p, n: int) -> QuasiStaticResult:
    """Step the battery over a demand from ``initial_soc`` (2-9..2-17); also used by topology.py."""
    batt = _Battery(p, n)
    soc = np.broadcast_to(p["initial_soc"], (n,)).astype(float)
    energy = np.zeros(n)
    regen = np.zeros(n)
    soc_min = soc.copy()
    for k in range(d.dt.shape[0]):
        power, e, soc = batt.step(soc, d.p_drive_w[k], d.p_regen_w[k], d.dt[k, 0])
        energy += e
        regen -= np.minimum(power, 0.0) * d.dt[k, 0]
        soc_min = np.minimum(soc_min, soc)
    km = d.distance_m / 1e3
    return QuasiStaticResult(energy / 3600.0 / km, d.distance_m, soc, d.speed_max, d.torque_margin,
                             d.torque_margin >= -1e-9, d.speed_max <= d.speed_limit,
                             regen / 3600.0 / km, soc_min, batt.power_room_w / 1e3, batt.current_room)


def energy_wh_per_km(resampled, params, vehicle_mass_kg, gear_ratio, motor_kw, *,
                     battery_kwh=DEFAULT_BATTERY_KWH, motor_map: MotorMap | None = None) -> np.ndarray:
    """Battery-terminal energy per km over one cycle (eqs 2-16, 2-17), shape (N,)."""
    return simulate(resampled, params, vehicle_mass_kg, gear_ratio, motor_kw, battery_kwh,
                    motor_map=motor_map).energy_wh_per_km


def range_by_repeated_cycle_km(resampled, params, vehicle_mass_kg, gear_ratio, motor_kw, battery_kwh, *,
                               motor_map: MotorMap | None = None, max_repeats: int = 200,
                               reference: bool = False) -> np.ndarray:
    """Chapter-3 range: repeat the cycle from 100 % SOC until ``final_soc`` (5 %), shape (N,).

    The crossing is interpolated linearly inside the step. Points still above
    ``final_soc`` after ``max_repeats`` cycles get ``inf``. The demand is computed once; only
    the battery steps through the repeats."""
    m, ig, kw, p = inputs(params, vehicle_mass_kg, gear_ratio, motor_kw, battery_kwh)
    step_m = step_distances_m(resampled)
    model = drive_model(p, motor_map)
    if reference:
        return integrate_range(demand(resampled, p, m, ig, kw, model), p, m.shape[0], step_m, max_repeats)
    return fast_range(fast_demand(resampled, p, m, ig, kw, model), p, m.shape[0], step_m, max_repeats)


def step_distances_m(resampled) -> np.ndarray:
    """Distance of every cycle step at its mean speed (6-50), m."""
    v = np.asarray(resampled.speed_m_s, float)
    return 0.5 * (v[1:] + v[:-1]) * np.diff(np.asarray(resampled.time_s, float))


def integrate_range(d: Demand, p, n: int, step_m: np.ndarray, max_repeats: int = 200) -> np.ndarray:
    """Repeat a demand from 100 % SOC down to ``final_soc`` (ch.3 range, km); also used by topology.py."""
    batt = _Battery(p, n)
    soc = np.ones(n)
    stop = np.broadcast_to(p["final_soc"], (n,))
    rng = np.full(n, np.inf)
    done = np.zeros(n, bool)
    travelled = 0.0
    for _ in range(max_repeats):
        for k in range(d.dt.shape[0]):
            _, _, new = batt.step(soc, d.p_drive_w[k], d.p_regen_w[k], d.dt[k, 0])
            hit = (~done) & (new <= stop)
            if hit.any():
                frac = (soc[hit] - stop[hit]) / np.maximum(soc[hit] - new[hit], 1e-300)
                rng[hit] = travelled + frac * step_m[k]
                done |= hit
            soc = new
            travelled += step_m[k]
        if done.all():
            break
    return rng / 1e3
