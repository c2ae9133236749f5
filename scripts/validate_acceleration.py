"""The 0-100 km/h model against published times of real cars (docs/validation.md "Acceleration").

Every car of bev_mdo/data/epa_2022_bev/acceleration.csv (published times, with their sources) is built
from its row of the training fleet file as ``bev-mdo validate`` builds it: test mass, the EPA coast-down
A + B v + C v^2, rated power, the fleet-wide gear ratio 9.0 and wheel radius 0.35 m, its driven axles;
everything else at the model's defaults (``VEHICLE_SPECS``: gear efficiency 0.97, tyre grip 1.0, 60 % of
the weight on one driven axle). The time is :func:`bev_mdo.models.acceleration.accel_time_s` to the
published target speed: 100 km/h, or 60 mph (96.56 km/h) where the maker published 0-60 mph (run to
60 mph, not converted). Variants:

* ``3.5 Nm/kW``: the model's default peak torque per kW (the thesis' Leaf; config/leaf_epa_combined.yaml);
* ``3.5, no grip``: the same without the tyre-grip limit (``tyre_grip_coefficient`` 0);
* ``2.0 Nm/kW``: the value the calibrated parameter sets carry (epa2022_chain / epa2022_quasi_static);
* ``published torque``: the car's published peak torque / its rated power, where known;
* ``published, no grip``: the same without the grip limit.

Then two diagnostics of what the error is made of (the model is grip-bound from rest, then at constant
rated power, so at 3.5 Nm/kW the torque-per-kW value matters little): the signed error with the rated
power scaled by a fleet-wide factor (``--power-share``), and the share of each car's model time spent
grip-bound.

    PYTHONPATH=. python scripts/validate_acceleration.py [--json] [--power-share 0.8]

A research tool, not shipped; the numbers are in docs/validation.md.
"""
from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

import numpy as np

from bev_mdo.models import fleet as fl
from bev_mdo.models.acceleration import accel_time_s, grip_force_n
from bev_mdo.models.params import VEHICLE_SPECS

ACCELERATION_CSV = fl.DATA_DIR / "acceleration.csv"
TARGET_M_S = {"100 km/h": 100.0 / 3.6, "60 mph": 60.0 * 0.44704}
VARIANTS = ("3.5 Nm/kW", "3.5, no grip", "2.0 Nm/kW", "published torque", "published, no grip")


def read_published(path: str | Path = ACCELERATION_CSV) -> list[dict]:
    """The rows of the published-times file, as strings (``unknown`` where no source gave a value)."""
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def car_params(fleet: fl.Fleet, i: int, **overrides) -> dict:
    """Model parameters of fleet row index ``i`` as ``bev-mdo validate`` builds them, plus ``overrides``."""
    p = {k: s.default for k, s in VEHICLE_SPECS.items()}
    p.update(wheel_radius_m=fl.FLEET_WHEEL_RADIUS_M, driven_axles=float(fleet.driven_axles[i]),
             road_load_a_n=float(fleet.road_load_a_n[i]), road_load_b_n_per_m_s=float(fleet.road_load_b_n_per_m_s[i]),
             road_load_c_n_per_m2_s2=float(fleet.road_load_c_n_per_m2_s2[i]), road_load_mass_kg=0.0)
    p.update(overrides)
    return p


def model_time_s(fleet: fl.Fleet, i: int, v_end_m_s: float, power_share: float = 1.0, **overrides) -> float:
    """The model's time from rest to ``v_end_m_s`` for fleet row index ``i`` (s)."""
    kw = np.array([fleet.rated_power_kw[i] * power_share])
    return float(accel_time_s(kw, np.array([fleet.gear_ratio[i]]), np.array([fleet.test_mass_kg[i]]),
                              car_params(fleet, i, **overrides), v_end_m_s)[0])


def grip_bound_share(fleet: fl.Fleet, i: int, v_end_m_s: float, **overrides) -> float:
    """Share of the model's time spent at the grip limit (0 where the grip never binds)."""
    p = car_params(fleet, i, **overrides)
    m, kw = fleet.test_mass_kg[i], fleet.rated_power_kw[i]
    grip = float(grip_force_n(m, p))
    # the grip binds from rest exactly while the peak-torque wheel force exceeds it, up to P eta / F_grip
    peak_force = p["motor_torque_per_kw"] * kw * fleet.gear_ratio[i] * p["gear_efficiency"] / p["wheel_radius_m"]
    if not np.isfinite(grip) or peak_force <= grip:
        return 0.0
    v_grip = min(1000.0 * kw * p["gear_efficiency"] / grip, v_end_m_s)
    return model_time_s(fleet, i, v_grip, **overrides) / model_time_s(fleet, i, v_end_m_s, **overrides)


def evaluate(power_share: float = 1.0, fleet: fl.Fleet | None = None, published: list[dict] | None = None) -> dict:
    """Per car: published and model times per variant, signed % error (model / published - 1); summary
    per variant: n, MAPE, mean signed error, and the same for the rated power x ``power_share``."""
    fleet = fleet or fl.read_fleet()
    published = published or read_published()
    cars = []
    for row in published:
        i = int(row["row"]) - 2
        if (fleet.make[i], fleet.model[i]) != (row["make"], row["model"]):
            raise ValueError(f"{ACCELERATION_CSV.name}: row {row['row']} is {row['make']} {row['model']}, "
                             f"the fleet file's row is {fleet.make[i]} {fleet.model[i]}")
        if row["published_time_s"] == "unknown":
            continue
        v_end, t_pub = TARGET_M_S[row["published_to"]], float(row["published_time_s"])
        kw = float(fleet.rated_power_kw[i])
        torque = None if row["peak_torque_nm"] == "unknown" else float(row["peak_torque_nm"])
        times = {"3.5 Nm/kW": model_time_s(fleet, i, v_end, motor_torque_per_kw=3.5),
                 "3.5, no grip": model_time_s(fleet, i, v_end, motor_torque_per_kw=3.5, tyre_grip_coefficient=0.0),
                 "2.0 Nm/kW": model_time_s(fleet, i, v_end, motor_torque_per_kw=2.0)}
        if torque is not None:
            k = torque / kw
            times["published torque"] = model_time_s(fleet, i, v_end, motor_torque_per_kw=k)
            times["published, no grip"] = model_time_s(fleet, i, v_end, motor_torque_per_kw=k,
                                                       tyre_grip_coefficient=0.0)
        times["power share"] = model_time_s(fleet, i, v_end, power_share, motor_torque_per_kw=3.5)
        cars.append({"row": int(row["row"]), "car": f"{row['make']} {row['model']}", "drive": fleet.drive[i],
                     "rated_power_kw": kw, "test_mass_kg": float(fleet.test_mass_kg[i]),
                     "published_to": row["published_to"], "published_s": t_pub, "peak_torque_nm": torque,
                     "torque_per_kw": None if torque is None else torque / kw,
                     "grip_bound_share": grip_bound_share(fleet, i, v_end, motor_torque_per_kw=3.5),
                     "model_s": times,
                     "error_pct": {v: 100.0 * (t / t_pub - 1.0) for v, t in times.items()}})
    summary = {}
    for v in (*VARIANTS, "power share"):
        e = np.array([c["error_pct"][v] for c in cars if v in c["error_pct"]])
        summary[v] = {"n": int(e.size), "mape_pct": float(np.mean(np.abs(e))),
                      "mean_signed_pct": float(np.mean(e)), "min_pct": float(e.min()), "max_pct": float(e.max())}
    return {"power_share": power_share, "cars": cars, "summary": summary}


def print_table(result: dict) -> None:
    cols = VARIANTS
    print(f"{'row':>3} {'car':<44} {'drv':>3} {'kW':>5} {'kg':>5} {'Nm/kW':>5} {'to':>8} {'pub s':>5}  "
          + "  ".join(f"{c:>18}" for c in cols) + f"  {'grip share':>10}")
    for c in result["cars"]:
        cells = []
        for v in cols:
            cells.append(f"{c['model_s'][v]:6.2f} ({c['error_pct'][v]:+5.1f} %)" if v in c["model_s"]
                         else f"{'-':>18}")
        tpk = "-" if c["torque_per_kw"] is None else f"{c['torque_per_kw']:.2f}"
        print(f"{c['row']:>3} {c['car'][:44]:<44} {c['drive']:>3} {c['rated_power_kw']:5.0f} {c['test_mass_kg']:5.0f} "
              f"{tpk:>5} {c['published_to']:>8} {c['published_s']:5.1f}  " + "  ".join(f"{x:>18}" for x in cells)
              + f"  {c['grip_bound_share']:10.2f}")
    print("\nvariant (model time vs published)     n    MAPE %   mean signed %   range %")
    for v, s in result["summary"].items():
        name = v if v != "power share" else f"3.5 Nm/kW, power x {result['power_share']:g}"
        print(f"{name:<34} {s['n']:>3} {s['mape_pct']:9.1f} {s['mean_signed_pct']:+15.1f}   "
              f"{s['min_pct']:+.1f} .. {s['max_pct']:+.1f}")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--json", action="store_true", help="print the result as JSON")
    ap.add_argument("--power-share", type=float, default=0.8,
                    help="diagnostic: the rated power scaled by this factor (default 0.8)")
    args = ap.parse_args(argv)
    result = evaluate(args.power_share)
    print(json.dumps(result, indent=1) if args.json else "", end="")
    if not args.json:
        print_table(result)


if __name__ == "__main__":
    main()
