"""Reference columns for a fleet validation: the 3-constant baseline and FASTSim 2.1.5's results.

* **3-constant baseline**: per cycle, ``E = a + b M + c W_road`` (Wh/km from the wall), with M the
  test mass (kg) and W_road the road-load work per km on that cycle (Wh/km, the coast-down
  A + B v + C v^2 integrated over the cycle). Fitted per cycle with ``numpy.linalg.lstsq`` on the
  relative error (each row divided by its measured energy) on the training folds only of a
  family-grouped k-fold split (:func:`family_folds`, the rule of ``fleet.group_folds``): every
  vehicle is predicted by constants that never saw its family.
* **FASTSim 2.1.5 with its defaults**: read from ``fastsim_2.1.5.csv`` beside the shipped fleet
  file, written by ``scripts/fastsim_baseline.py`` (which needs FASTSim; reading does not). A fleet
  row is matched to a run by its make, model and the inputs FASTSim was run on (drive, rated power,
  test mass, A, B, C, kept in the file), wherever it sits in the file: a row FASTSim was not run on
  gets no FASTSim figure.

:func:`reference_table` scores any set of such columns on the same rows: per cycle, the rows every
column scores, their mean absolute % error and the within-family pair metrics (models/pairs.py).
Pure numpy.
"""
from __future__ import annotations

import csv
import math

import numpy as np

from . import fleet as fl
from . import pairs as pr

FASTSIM_CSV = fl.DATA_DIR / "fastsim_2.1.5.csv"
# the fleet columns FASTSim's vehicle is built from (scripts/fastsim_baseline.py), kept per row in its file
FASTSIM_INPUTS = ("drive", "rated_power_kw", "test_mass_kg", "road_load_a_n", "road_load_b_n_per_m_s",
                  "road_load_c_n_per_m2_s2")
FOLDS = 5


def family_folds(fleet: fl.Fleet, use: np.ndarray, k: int = FOLDS) -> np.ndarray:
    """Fold of every row (-1 where ``use`` is False): the families of the used rows dealt to k folds
    in order of size, a family never split (the same split as ``calibrate.cross_validate``)."""
    groups = fleet.family()
    idx = np.flatnonzero(use)
    folds = np.full(len(fleet), -1)
    folds[idx] = fl.group_folds([groups[i] for i in idx], k)[0]
    return folds


def road_load_wh_per_km(fleet: fl.Fleet, cycles: dict | None = None) -> dict[str, np.ndarray]:
    """Per cycle, each vehicle's road-load work per km (Wh/km): the coast-down force A + B v + C v^2
    (acting while moving) times the distance, over the distance, from the cycle's speed moments."""
    from .cycles import quadrature

    cycles = cycles or fl.resampled_cycles()
    out = {}
    for name, r in cycles.items():
        v, _, _, w = quadrature(r)
        dist = float(np.sum(w * v))
        m2, m3 = float(np.sum(w * v**2)) / dist, float(np.sum(w * v**3)) / dist
        out[name] = (fleet.road_load_a_n + fleet.road_load_b_n_per_m_s * m2
                     + fleet.road_load_c_n_per_m2_s2 * m3) / 3.6  # N -> Wh/km
    return out


def three_constant_cv(fleet: fl.Fleet, use: np.ndarray, cycles: dict | None = None,
                      k: int = FOLDS) -> dict[str, np.ndarray]:
    """Held-out predictions of the 3-constant baseline, {cycle: (N,) Wh/km}, NaN where ``use`` is
    False or the other folds' rows do not fix the 3 constants. A row's prediction comes from constants
    fitted on the other folds only."""
    use = np.asarray(use, bool)
    folds = family_folds(fleet, use, k)
    work = road_load_wh_per_km(fleet, cycles)
    out = {}
    for c in fl.CYCLES:
        X = np.column_stack([np.ones(len(fleet)), fleet.test_mass_kg, work[c]])
        y = fleet.measured[c]
        pred = np.full(len(fleet), np.nan)
        for i in range(folds.max() + 1):
            test, train = folds == i, use & (folds != i)
            A = X[train] / y[train, None]
            if np.linalg.matrix_rank(A) < X.shape[1]:  # the rows do not fix 3 constants (lstsq answers anyway)
                continue
            coef = np.linalg.lstsq(A, np.ones(int(train.sum())), rcond=None)[0]
            pred[test] = X[test] @ coef
        out[c] = pred
    return out


def read_fastsim(fleet: fl.Fleet, path=None) -> dict[str, np.ndarray] | None:
    """FASTSim's wall energy per cycle for the fleet's rows, {cycle: (N,) Wh/km}, NaN where the file
    has no run of that vehicle (the same make, model and :data:`FASTSIM_INPUTS`, wherever the row is in
    the file: a reordered or partial copy keeps its figures, an edited row loses its own) or FASTSim could
    not follow the trace; None when the file is absent."""
    path = path or FASTSIM_CSV
    try:
        with open(path, newline="", encoding="utf-8") as f:
            rows = list(csv.DictReader(line for line in f if not line.startswith("#")))
    except OSError:
        return None
    runs: dict[tuple[str, str], list[dict]] = {}
    for r in rows:  # matched by the vehicle, not the row number (it moved with a reordered copy)
        runs.setdefault((r["make"], r["model"]), []).append(r)

    def same(r, i):
        return r["drive"] == fleet.drive[i] and all(
            math.isclose(float(r[k]), float(getattr(fleet, k)[i]), rel_tol=1e-9) for k in FASTSIM_INPUTS[1:])
    found = [next((r for r in runs.get((fleet.make[i], fleet.model[i]), []) if same(r, i)), None)
             for i in range(len(fleet))]
    run_on = [r is not None for r in found]
    out = {}
    for c in fl.CYCLES:
        short = c.replace("epa_", "")
        out[c] = np.array([float(r[f"{short}_wh_per_km_ac"]) if ok and r[f"{short}_trace_met"] == "yes" else np.nan
                           for r, ok in zip(found, run_on)])
    return out


def reference_table(fleet: fl.Fleet, columns: dict[str, dict], scored: dict[str, dict] | None = None) -> dict:
    """Score ``columns`` ({name: {cycle: (N,) predicted Wh/km}}) on the same rows: per cycle, the
    non-outlier rows where every column has a finite prediction (and ``scored[name][cycle]`` where
    given). Returns {cycle: {"rows": n, "pairs": n, name: {"mape_pct", "pair_slope", "pair_mad_points"}}}."""
    scored = scored or {}
    found = pr.find_pairs(fleet.model_line(), fleet.drive, fleet.rated_power_kw, fleet.test_mass_kg, ~fleet.outlier)
    out = {}
    for c in fl.CYCLES:
        ok = ~fleet.outlier
        for name, col in columns.items():
            ok = ok & np.isfinite(col[c])
            if name in scored:
                ok = ok & scored[name][c]
        both = [(a, b) for a, b in found if ok[a] and ok[b]]
        meas = pr.pct_diff(fleet.measured[c], both)
        cell = {"rows": int(ok.sum()), "pairs": len(both)}
        for name, col in columns.items():
            err = 100.0 * np.abs(col[c][ok] / fleet.measured[c][ok] - 1.0)
            s = pr.pair_stats(meas, pr.pct_diff(col[c], both))
            cell[name] = {"mape_pct": float(err.mean()) if err.size else math.nan,
                          "pair_slope": s["slope_through_origin"], "pair_mad_points": s["mean_abs_diff_points"]}
        out[c.replace("epa_", "")] = cell
    return out
