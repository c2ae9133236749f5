"""FASTSim 2.1.5 with its defaults on a fleet file: the reference column of ``bev-mdo validate``.

Builds one FASTSim battery-electric vehicle per fleet row the way FASTSim's own vehicle import
does (``try_make_single_vehicle`` in fastsim-core's ``vehicle_import.rs``, used by
``fastsim/demos/vehicle_import_demo.py``): FASTSim's default vehicle with, for a BEV, mass
override = test mass, ``mc_max_kw`` = rated power, aux 0.25 kW, transmission efficiency 0.98, an
all-zero motor map with a 0.95 peak override (FASTSim then takes its large-motor baseline map),
centre of gravity +0.53 m for front drive and -0.53 m otherwise, and drag and rolling-resistance
coefficients fitted to the row's coast-down A, B, C by FASTSim's ``abc_to_drag_coeffs`` (its
coast-down simulation, ``simdrive_optimize=True``, as the import does). The fleet file has no pack
size, width or height: the pack is 75 kWh (bev_mdo's fleet-wide value), ``ess_max_kw`` 1.2 x rated
power (not binding on UDDS or HWFET), and the frontal area FASTSim's default (only the product
drag coefficient x area matters once the coefficient is fitted to C). Each vehicle runs FASTSim's
own ``udds`` and ``hwfet`` cycles unadjusted (``sim_drive``); the energy from the wall is FASTSim's
``battery_kwh_per_mi`` over the vehicle's charger efficiency (``chg_eff`` 0.86, FASTSim's default,
as its ``simdrivelabel.get_label_fe`` does for a BEV).

FASTSim pins numpy 2.0 and pandas 2, which conflict with constraints.txt, so it runs in its own
virtual environment and writes a CSV that bev_mdo reads (``bev_mdo/models/baselines.py``); neither
``validate`` nor the tests need FASTSim installed::

    python3.11 -m venv /tmp/fastsim && /tmp/fastsim/bin/pip install -r bench/requirements-fastsim.txt
    PYTHONPATH=. /tmp/fastsim/bin/python scripts/fastsim_baseline.py [--data CSV] [--out CSV]
"""
from __future__ import annotations

import argparse
import contextlib
import csv
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bev_mdo.models import fleet as fl  # noqa: E402
from bev_mdo.models.baselines import FASTSIM_INPUTS  # noqa: E402

N_PER_LBF = 4.4482216152605
M_S_PER_MPH = 0.44704
M_PER_MI = 1609.344
BATTERY_KWH = fl.FLEET_BATTERY_KWH
ESS_KW_PER_MOTOR_KW = 1.2
DEFAULT_OUT = fl.DATA_DIR / "fastsim_2.1.5.csv"


@contextlib.contextmanager
def _quiet_stderr():
    """FASTSim's coast-down fit logs an energy-audit warning per iteration on fd 2."""
    saved = os.dup(2)
    with open(os.devnull, "w") as null:
        os.dup2(null.fileno(), 2)
        try:
            yield
        finally:
            os.dup2(saved, 2)
            os.close(saved)


def build_vehicle(fsr, fleet: fl.Fleet, i: int):
    """One FASTSim BEV from fleet row ``i`` (vehicle_import.rs, try_make_single_vehicle, BEV branch)."""
    d = fsr.RustVehicle.mock_vehicle().to_pydict()  # RustVehicle::default()
    n_mc = len(d["mc_eff_map"]["data"])
    kw = float(fleet.rated_power_kw[i])
    d.update(
        scenario_name=f"{fleet.make[i]} {fleet.model[i]}", veh_pt_type="BEV", veh_year=2022,
        veh_override_kg=float(fleet.test_mass_kg[i]), veh_cg_m=0.53 if fleet.drive[i] == "F" else -0.53,
        fs_max_kw=0.0, fs_kwh=0.0, fc_max_kw=0.0, fc_eff_type="SI", idle_fc_kw=0.0,
        fc_eff_map={"v": 1, "dim": [12], "data": [0.10, 0.12, 0.16, 0.22, 0.28, 0.33, 0.35, 0.36, 0.35, 0.34,
                                                  0.32, 0.30]},
        mc_max_kw=kw, mc_eff_map={"v": 1, "dim": [n_mc], "data": [0.0] * n_mc}, mc_peak_eff_override=0.95,
        min_soc=0.0, max_soc=1.0, ess_max_kw=ESS_KW_PER_MOTOR_KW * kw, ess_max_kwh=BATTERY_KWH,
        mph_fc_on=1.0, kw_demand_fc_on=100.0, aux_kw=0.25, trans_eff=0.98, ess_dischg_to_fc_max_eff_perc=0.0,
        stop_start=False, force_aux_on_fc=False)
    veh = fsr.RustVehicle.from_pydict(d)
    veh.set_derived()
    a_lbf = float(fleet.road_load_a_n[i]) / N_PER_LBF
    b_lbf_mph = float(fleet.road_load_b_n_per_m_s[i]) * M_S_PER_MPH / N_PER_LBF
    c_lbf_mph2 = float(fleet.road_load_c_n_per_m2_s2[i]) * M_S_PER_MPH ** 2 / N_PER_LBF
    with _quiet_stderr():
        fsr.abc_to_drag_coeffs(veh, a_lbf, b_lbf_mph, c_lbf_mph2, False, None, None, True, False)
    return veh


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=None, help="fleet CSV (default: the shipped training file)")
    ap.add_argument("--out", default=str(DEFAULT_OUT), help=f"CSV to write (default {DEFAULT_OUT.relative_to(ROOT)})")
    args = ap.parse_args(argv)
    import fastsim
    import fastsim.fastsimrust as fsr

    fleet = fl.read_fleet(args.data)
    cycles = {"udds": fastsim.cycle.Cycle.from_file("udds").to_rust(),
              "hwfet": fastsim.cycle.Cycle.from_file("hwfet").to_rust()}
    rows = []
    for i in range(len(fleet)):
        veh = build_vehicle(fsr, fleet, i)
        out = {"row": int(fleet.rows[i]), "make": fleet.make[i], "model": fleet.model[i],
               **{k: getattr(fleet, k)[i] if k == "drive" else repr(float(getattr(fleet, k)[i]))
                  for k in FASTSIM_INPUTS},  # what the row was run on: read_fastsim matches them
               "drag_coef": f"{veh.drag_coef:.6f}", "wheel_rr_coef": f"{veh.wheel_rr_coef:.6f}"}
        for name, cyc in cycles.items():
            sd = fsr.RustSimDrive(cyc, veh)
            with _quiet_stderr():
                sd.sim_drive()
            wall_wh_per_km = sd.battery_kwh_per_mi / veh.chg_eff * 1e6 / M_PER_MI
            out[f"{name}_wh_per_km_ac"] = f"{wall_wh_per_km:.4f}"
            out[f"{name}_trace_met"] = "yes" if not sd.trace_miss else "no"
        rows.append(out)
        print(f"row {out['row']:3d} {fleet.make[i][:10]:10} {fleet.model[i][:34]:34} UDDS {out['udds_wh_per_km_ac']:>9} "
              f"HWFET {out['hwfet_wh_per_km_ac']:>9} Wh/km", flush=True)
    data = Path(args.data) if args.data else fl.DEFAULT_FLEET
    shown = data.resolve().relative_to(ROOT) if data.resolve().is_relative_to(ROOT) else data
    with open(args.out, "w", newline="", encoding="utf-8") as f:
        f.write(f"# FASTSim {fastsim.__version__} with its defaults (scripts/fastsim_baseline.py) on {shown};\n"
                f"# vehicles built as FASTSim's vehicle import builds a BEV; wall energy = battery_kwh_per_mi / chg_eff "
                f"({veh.chg_eff}); pack {BATTERY_KWH} kWh, ess_max_kw {ESS_KW_PER_MOTOR_KW} x rated power\n"
                "# the fleet file's inputs FASTSim was run on (drive, rated power, test mass, A, B, C) are kept per row:\n"
                "# a fleet row whose inputs differ gets no FASTSim figure\n")
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print(f"{len(rows)} vehicles written to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
