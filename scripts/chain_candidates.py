"""Candidate physics for the wall-to-wheel chain, scored exactly as calibrate.py scores the shipped
model: least squares on relative error over the fleet file, 5-fold CV by model family and
leave-one-make-out CV (docs/validation.md "Limits: what was tried and the ceiling").

Each candidate is a chain variant (``sim``: the shipped chain.simulate plus optional terms, all
fleet-wide parameters, off by default) and a set of fitted parameters.
``PYTHONPATH=. python scripts/chain_candidates.py [NAME ...]`` prints train / family CV / LOMO mean
absolute % error (UDDS / HWFET in brackets) and the full-fleet fit with Gauss-Newton standard errors
("(BOUND)" where a parameter ends on its bound). The "shipped" row reproduces calibrate.py
(7.81 / 7.98 / 9.16 %). A research tool, not part of the package: nothing here is shipped.
"""
from __future__ import annotations

import sys
import time

import numpy as np
from scipy.optimize import least_squares

from bev_mdo.models import calibrate as cal
from bev_mdo.models import chain
from bev_mdo.models import fleet as fl
from bev_mdo.models import road_load as rl

EXTRA = {  # extra terms, all off by default (= the shipped chain)
    "iron_loss_fraction": 0.0,      # P_r c_fe s^n, s = motor speed / base speed
    "iron_loss_exponent": 1.5,
    "regen_decel_max_m_s2": np.inf,  # regen force <= M a_max (friction blending above)
    "regen_efficiency": 1.0,         # extra factor on recovered electrical power (< 1: worse round trip)
    "traction_efficiency": 1.0,      # extra factor dividing the electrical traction power
    "raf_resistance_ohm": 0.0,       # J1634: battery loss allocated test-wide (CSC at 65 mph reference)
    "raf_csc_share": 0.0,            # share of the test's DC energy in the constant-speed phases
    "inverter_current_fraction": 0.0,  # P_r c_i tau  (switching/conduction ~ current)
}


def sim(r, p, fleet, gear=None):
    """chain.simulate with the EXTRA terms; p: dict of scalars or (N,) arrays."""
    n = len(fleet)
    m = fleet.test_mass_kg
    ig = fleet.gear_ratio if gear is None else gear
    kw = fleet.rated_power_kw
    q = {**fl.fleet_params(fleet, {k: v for k, v in p.items() if k not in EXTRA})}
    P = {k: chain._col(v) for k, v in chain.resolve(q, n).items()}
    x = {k: chain._col(np.broadcast_to(np.asarray(p.get(k, d), float), (n,)) if np.ndim(p.get(k, d)) else p.get(k, d))
         for k, d in EXTRA.items()}
    v, a, w, dur, dist, v_lo, v_hi = chain._steps(r)
    M = m[None, :]
    force = rl.road_load_n(P, v, M) + M * (1.0 + P["rotating_mass_fraction"]) * a
    r_w, eta = P["wheel_radius_m"], P["gear_efficiency"]
    i_g, p_r = ig[None, :], kw[None, :] * 1e3
    omega = v * i_g / r_w
    t_pk = P["motor_torque_per_kw"] * kw[None, :]
    driving = force >= 0
    t_drive = np.where(driving, force * r_w / (i_g * eta), 0.0)
    f_brake = P["regen_axle_share"] * force
    f_brake = np.maximum(f_brake, -M * x["regen_decel_max_m_s2"])
    t_brake = np.where(driving, 0.0, f_brake * r_w * eta / i_g)
    p_regen_cap = np.minimum(p_r, P["regen_max_power_kw"] * 1e3)
    t_regen_cap = np.minimum(t_pk, p_regen_cap / np.maximum(omega, 1e-9))
    v_min = P["regen_min_speed_m_s"]
    phi = np.clip((v_hi - v_min) / np.maximum(v_hi - v_lo, 1e-12), 0.0, 1.0)
    phi = np.where(v_lo >= v_min, 1.0, np.where(v_hi < v_min, 0.0, phi))
    t_regen = np.where(phi > 0, np.maximum(t_brake, -t_regen_cap), 0.0)
    torque = t_drive + t_regen
    w_base = 1000.0 / P["motor_torque_per_kw"]
    tau = np.abs(torque) / t_pk
    s = omega / w_base
    idle = p_r * (P["motor_loss_standby_fraction"] + P["motor_loss_speed_fraction"] * s
                  + x["iron_loss_fraction"] * s ** x["iron_loss_exponent"])
    loss = idle + p_r * (P["motor_loss_copper_fraction"] * tau * tau + x["inverter_current_fraction"] * tau)
    mech = torque * omega
    p_el = np.where(mech >= 0, mech / x["traction_efficiency"], mech * x["regen_efficiency"]) + loss
    p_el = np.where(driving, p_el, phi * np.minimum(p_el, idle) + (1.0 - phi) * idle)
    volt = P["battery_voltage_v"]
    r_b = np.where(p_el >= 0, P["battery_discharge_resistance_ohm"], P["battery_charge_resistance_ohm"])
    p_batt = p_el + r_b * (p_el / volt) ** 2
    e_batt = w[:, 0] @ p_batt + np.broadcast_to(P["aux_power_w"], (1, n))[0] * dur
    km = dist / 1e3
    eta_chg = np.broadcast_to(P["charger_efficiency"], (1, n))[0]
    batt = e_batt / 3600.0 / km
    # J1634 recharge allocation: one test-wide factor AC/DC per vehicle; battery loss over the test
    # (constant-speed phases at 65 mph dominate a multi-cycle test) spread over the cycles by DC energy
    if np.any(np.asarray(x["raf_resistance_ohm"]) > 0):
        v65 = 65 * 0.44704
        p65 = (rl.road_load_n(P, np.array([[v65]]), M)[0] * v65 / eta) + np.broadcast_to(P["aux_power_w"], (1, n))[0]
        frac = np.broadcast_to(x["raf_resistance_ohm"], (1, n))[0] * p65 / np.broadcast_to(volt, (1, n))[0] ** 2
        batt = batt * (1.0 + frac)
    return batt / eta_chg


def predict(fleet, p, cycles, gear=None):
    return {c: sim(r, p, fleet, gear) for c, r in cycles.items()}


class Candidate:
    def __init__(self, name, fit, fixed=None, per_vehicle=None, loss="linear", f_scale=0.05, gear=None,
                 family_weights=False):
        self.name, self.fitspec, self.fixed = name, dict(fit), dict(fixed or {})
        self.per_vehicle = per_vehicle  # callable(fleet, params) -> params (per-vehicle arrays)
        self.loss, self.f_scale, self.gear = loss, f_scale, gear
        self.family_weights = family_weights  # each model family weighs the same in the fit (1/sqrt(rows))

    def params(self, fleet, names, x, mask=None):
        p = {**cal.FIXED, **self.fixed, **dict(zip(names, x))}
        if self.per_vehicle:
            p = self.per_vehicle(fleet, p)
        return p

    def rel(self, fleet, names, x, mask, cycles):
        p = self.params(fleet, names, x)
        g = self.gear(fleet) if self.gear else None
        pred = predict(fleet, p, cycles, g)
        return np.concatenate([pred[c][mask] / fleet.measured[c][mask] - 1.0 for c in fl.CYCLES])

    def fit(self, fleet, mask, cycles):
        names = tuple(self.fitspec)
        x0 = np.array([self.fitspec[k][0] for k in names])
        lo = np.array([self.fitspec[k][1] for k in names])
        hi = np.array([self.fitspec[k][2] for k in names])

        wt = np.ones(int(mask.sum()))
        if self.family_weights:
            fam = np.array(fleet.family())[mask]
            _, inv, cnt = np.unique(fam, return_inverse=True, return_counts=True)
            wt = 1.0 / np.sqrt(cnt[inv])
        wt = np.concatenate([wt] * len(fl.CYCLES))

        def res(x):
            e = self.rel(fleet, names, x, mask, cycles)
            return wt * (np.log1p(e) if self.loss == "log" else e)

        kw = dict(loss="soft_l1", f_scale=self.f_scale) if self.loss == "soft_l1" else {}
        out = least_squares(res, x0, bounds=(lo, hi), x_scale=np.maximum(np.abs(x0), 1e-3), diff_step=1e-6,
                            method="trf", **kw)
        n, k = out.fun.size, len(names)
        fun = res(out.x)
        s2 = float(fun @ fun) / max(n - k, 1)
        try:
            se = np.sqrt(np.clip(np.diag(s2 * np.linalg.inv(out.jac.T @ out.jac)), 0, None))
        except np.linalg.LinAlgError:
            se = np.full(k, np.nan)
        at_bound = (np.isclose(out.x, lo, rtol=1e-4, atol=1e-9) | np.isclose(out.x, hi, rtol=1e-4, atol=1e-9))
        return names, out.x, se, at_bound

    def cv(self, fleet, cycles, groups, k):
        folds, k = fl.group_folds(groups, k)  # the folds calibrate.cross_validate uses
        err = {c: np.full(len(fleet), np.nan) for c in fl.CYCLES}
        for i in range(k):
            test = folds == i
            names, x, _, _ = self.fit(fleet, ~test & ~fleet.outlier, cycles)
            p = self.params(fleet, names, x)
            g = self.gear(fleet) if self.gear else None
            pred = predict(fleet, p, cycles, g)
            for c in fl.CYCLES:
                err[c][test] = 100 * (pred[c][test] / fleet.measured[c][test] - 1.0)
        return err


def score(cand, fleet, cycles):
    ok = ~fleet.outlier
    t0 = time.time()
    names, x, se, atb = cand.fit(fleet, ok, cycles)
    p = cand.params(fleet, names, x)
    g = cand.gear(fleet) if cand.gear else None
    pred = predict(fleet, p, cycles, g)
    tr = {c: 100 * (pred[c] / fleet.measured[c] - 1) for c in fl.CYCLES}
    fam = cand.cv(fleet, cycles, fleet.family(), 5)
    lomo = cand.cv(fleet, cycles, [m.lower() for m in fleet.make], 99)

    def m(err):
        a = np.concatenate([np.abs(err[c][ok]) for c in fl.CYCLES])
        return a.mean(), np.abs(err["epa_udds"][ok]).mean(), np.abs(err["epa_hwfet"][ok]).mean()

    vals = ", ".join(f"{k} {v:.4g} +- {s:.2g}{' (BOUND)' if b else ''}" for k, v, s, b in zip(names, x, se, atb))
    a, f, lo_ = m(tr), m(fam), m(lomo)
    pairs = cal.cv_pairs(fleet, {"errors_pct": fam}, ok)  # within-family pairs of the family CV
    pp = " / ".join(f"slope {pairs[c]['slope_through_origin']:.3f} diff {pairs[c]['mean_abs_diff_points']:.2f} pp"
                    for c in fl.CYCLES)
    print(f"{cand.name}: train {a[0]:.2f} | family CV {f[0]:.2f} ({f[1]:.2f} / {f[2]:.2f}) | "
          f"LOMO {lo_[0]:.2f} ({lo_[1]:.2f} / {lo_[2]:.2f}) | pairs (UDDS / HWFET) {pp} | {vals} | "
          f"{time.time() - t0:.0f} s", flush=True)
    return {"train": a, "family": f, "lomo": lo_, "x": dict(zip(names, x)), "se": dict(zip(names, se)),
            "fam_err": fam, "lomo_err": lomo, "train_err": tr, "pairs": pairs}


SHIPPED_FIT = dict(cal.FIT)


def _awd(fleet):
    return fleet.driven_axles == 2


def _listed_gear(fleet):
    """The axle_ratio column where it is plausible for a single reduction (>= 6), else the fleet's 9.0."""
    import csv

    with open(fleet.path, newline="") as f:
        ratio = np.array([float(r["axle_ratio"]) if r["axle_ratio"].strip() else np.nan for r in csv.DictReader(f)])
    return np.where(ratio >= 6, ratio, fl.FLEET_GEAR_RATIO)


def _awd_standby(fleet, p):
    """The second machine's no-load loss while moving (W, AWD only), as a per-vehicle c_0."""
    p = dict(p)
    extra_w = np.where(_awd(fleet), p.pop("awd_standby_w"), 0.0)
    return {**p, "motor_loss_standby_fraction": p["motor_loss_standby_fraction"]
            + extra_w / (fleet.rated_power_kw * 1e3)}


def _awd_standby_by_motor(kinds):
    """As _awd_standby, only for all-wheel-drive cars whose front machine (the one idling on the
    cycles) is of one of ``kinds`` (the motor_front technology column of the fleet file)."""
    def per_vehicle(fleet, p):
        p = dict(p)
        front = np.array(fleet.technology.get("motor_front", ["unknown"] * len(fleet)))
        extra_w = np.where(_awd(fleet) & np.isin(front, kinds), p.pop("awd_standby_w"), 0.0)
        return {**p, "motor_loss_standby_fraction": p["motor_loss_standby_fraction"]
                + extra_w / (fleet.rated_power_kw * 1e3)}
    return per_vehicle


def _rot_by_axles(fleet, p):
    """What turns on the dyno: one axle (2WD dyno) or both (AWD on a 4WD dyno)."""
    return {**p, "rotating_mass_fraction": np.where(_awd(fleet), 0.035, 0.02)}


def _regen_by_motors(fleet, p):
    p = dict(p)
    one, two = p.pop("regen_share_one_motor"), p.pop("regen_share_two_motors")
    return {**p, "regen_axle_share": np.where(_awd(fleet), two, one)}


def candidates():
    F = SHIPPED_FIT
    eta_chg = {"charger_efficiency": F["charger_efficiency"]}
    no_r = {"battery_discharge_resistance_ohm": 0.0, "battery_charge_resistance_ohm": 0.0}
    eta_tr = {"traction_efficiency": (0.9, 0.5, 1.0), "regen_efficiency": (0.8, 0.3, 1.0)}
    share1_chg90 = {"regen_axle_share": 1.0, "charger_efficiency": 0.90}
    regen_m = {**eta_chg, "regen_share_one_motor": (0.8, 0.2, 1.0), "regen_share_two_motors": (0.8, 0.2, 1.0)}
    C = {"shipped": Candidate("shipped", F)}
    # error models (same physics)
    C["log"] = Candidate("shipped, fit in log space", F, loss="log")
    C["soft_l1"] = Candidate("shipped, soft_l1 (f_scale 0.05)", F, loss="soft_l1", f_scale=0.05)
    C["soft_l1_02"] = Candidate("shipped, soft_l1 (f_scale 0.02)", F, loss="soft_l1", f_scale=0.02)
    C["family_weights"] = Candidate("shipped, every model family weighted equally in the fit", F,
                                    family_weights=True)
    # J1634 recharge allocation: battery loss test-wide (65 mph CSC reference)
    C["raf_R"] = Candidate("+ J1634 test-wide battery loss R (CSC 65 mph)",
                           {**F, "raf_resistance_ohm": (0.1, 0.0, 3.0)}, fixed=no_r)
    C["raf_fixed"] = Candidate("J1634 allocation of the fixed 0.08 ohm (no per-cycle P^2 loss)", F,
                               fixed={**no_r, "raf_resistance_ohm": 0.08})
    # motor + inverter losses in torque and speed
    C["iron15"] = Candidate("+ iron loss c_fe P_r s^1.5", {**F, "iron_loss_fraction": (0.005, 0.0, 0.1)})
    C["iron2"] = Candidate("+ iron loss c_fe P_r s^2", {**F, "iron_loss_fraction": (0.005, 0.0, 0.1)},
                           fixed={"iron_loss_exponent": 2.0})
    C["motor_full"] = Candidate("c_0, iron c_fe s^2, c_cu all fitted, listed gear >= 6", {
        **F, "motor_loss_standby_fraction": (0.001, 0.0, 0.05), "iron_loss_fraction": (0.005, 0.0, 0.1),
        "motor_loss_copper_fraction": (0.05, 0.0, 0.3)}, fixed={"iron_loss_exponent": 2.0}, gear=_listed_gear)
    C["inv"] = Candidate("+ inverter loss c_i P_r tau", {**F, "inverter_current_fraction": (0.01, 0.0, 0.2)})
    C["awd_standby"] = Candidate("+ no-load loss of the second machine (AWD), W while moving",
                                 {**F, "awd_standby_w": (200.0, 0.0, 3000.0)}, per_vehicle=_awd_standby)
    C["awd_standby_pmsm"] = Candidate("+ no-load loss of the second machine, AWD with a PMSM front machine",
                                      {**F, "awd_standby_w": (200.0, 0.0, 3000.0)},
                                      per_vehicle=_awd_standby_by_motor(["PMSM"]))
    C["awd_standby_not_induction"] = Candidate(
        "+ no-load loss of the second machine, AWD except an induction front machine",
        {**F, "awd_standby_w": (200.0, 0.0, 3000.0)}, per_vehicle=_awd_standby_by_motor(["PMSM", "EESM", "unknown"]))
    # regeneration: maximum deceleration (friction blending), round-trip efficiency, motors
    C["decel"] = Candidate("+ regen decel limit a_max", {**F, "regen_decel_max_m_s2": (1.0, 0.2, 3.0)})
    C["decel_share1"] = Candidate("regen decel limit a_max, axle share 1 (dyno)",
                                  {**eta_chg, "regen_decel_max_m_s2": (1.0, 0.2, 3.0)},
                                  fixed={"regen_axle_share": 1.0})
    C["eta_r"] = Candidate("+ regen efficiency eta_r (share 1)", {**eta_chg, "regen_efficiency": (0.8, 0.3, 1.0)},
                           fixed={"regen_axle_share": 1.0})
    C["eta_t_r"] = Candidate("eta_chg 0.90 fixed; traction eta_t, regen eta_r, share 1", eta_tr, fixed=share1_chg90)
    C["eta_t_r_aux"] = Candidate("eta_chg 0.90 fixed; eta_t, eta_r, aux, share 1",
                                 {**eta_tr, "aux_power_w": (300.0, 0.0, 2000.0)}, fixed=share1_chg90)
    C["regen_motors"] = Candidate("regen share by motors (F/R vs A/4/P)", regen_m, per_vehicle=_regen_by_motors)
    # dynamometer
    C["rot_axles"] = Candidate("rotating mass 2 % (2WD dyno) / 3.5 % (AWD, 4WD dyno)", F, per_vehicle=_rot_by_axles)
    # family weights combined with the best of the above
    C["fw_regen_motors"] = Candidate("family weights + regen share by motors", regen_m,
                                     per_vehicle=_regen_by_motors, family_weights=True)
    C["fw_eta_t_r"] = Candidate("family weights + eta_chg 0.90; eta_t, eta_r, share 1", eta_tr,
                                fixed=share1_chg90, family_weights=True)
    C["fw_soft_l1"] = Candidate("family weights + soft_l1 (f_scale 0.05)", F, loss="soft_l1", family_weights=True)
    return C

if __name__ == "__main__":
    fleet = fl.read_fleet()
    cycles = fl.resampled_cycles()
    C = candidates()
    for name in sys.argv[1:] or list(C):
        score(C[name], fleet, cycles)
