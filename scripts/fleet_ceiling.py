"""How far can ANY model of the fleet file's columns go? (docs/validation.md "Ceiling of the level: any model of these columns")

The 5 % target is a cross-validated mean absolute error with fleet-wide parameters, judged on unseen
model families. This script scores, with the same family-grouped 5-fold CV and leave-one-make-out
(LOMO) CV as ``calibrate.py``, models that are free of physics' constraints:

* linear models of the wheel work per km (positive work, braking work, time; then every subset of up
  to three extra work terms), fitted by least squares on relative error, signs unconstrained;
* ridge regression of log(measured / shipped chain) on every column plus work features, its penalty
  chosen inside each training fold by a nested family-grouped CV;
* k-nearest neighbours on the same features; random forest and gradient boosting if scikit-learn is
  importable (it is not a dependency of bev_mdo: ``pip install scikit-learn`` in a scratch venv);
* an oracle that knows the make (one offset per make, in sample): what the make name alone carries.

If none of them reaches 5 %, no fleet-wide model of these columns will. The subset search picks its
best row after seeing the CV errors, so that row is optimistic, which is the right direction for a
ceiling. ``PYTHONPATH=. python scripts/fleet_ceiling.py [--data CSV]``. A research tool, not shipped.
"""
from __future__ import annotations

import argparse
import itertools

import numpy as np

from bev_mdo.models import calibrate as cal
from bev_mdo.models import fleet as fl
from bev_mdo.models import road_load as rl
from bev_mdo.models.cycles import quadrature

EXTRA_TERMS = ("WA", "WB", "WC", "WI", "Q", "WpM", "TP", "Tawd", "WnAwd")


def work_features(fleet: fl.Fleet, cycles: dict) -> dict[str, np.ndarray]:
    """Per vehicle and cycle (cycles stacked), Wh/km at the wheels: positive work Wp, braking work Wn,
    time per km T (h/km, x1000 so that its coefficient is in W), the positive work split into road
    load A / B / C and inertia, a convex term Q (sum F^2 v / rated power) and three interactions."""
    m, kw = fleet.test_mass_kg, fleet.rated_power_kw
    awd = np.array([d in "A4P" for d in fleet.drive], float)
    p = fl.fleet_params(fleet, {})
    out: dict[str, list] = {}
    for name in fl.CYCLES:
        v, a, _, w = quadrature(cycles[name])
        v, a, w = v[:, None], a[:, None], w[:, None]
        dist = float((w * v).sum())
        f_inertia = 1.02 * m[None, :] * a
        f = rl.road_load_n(p, v, m[None, :]) + f_inertia
        pos = f > 0

        def wh_per_km(force, mask=pos):
            return (w * np.where(mask, force, 0.0) * v).sum(0) / dist / 3.6

        d = {"Wp": wh_per_km(f), "Wn": wh_per_km(-f, ~pos),
             "T": np.full(len(fleet), float(w.sum()) / dist / 3.6),
             "WA": wh_per_km(np.broadcast_to(fleet.road_load_a_n * (v > 0), f.shape)),
             "WB": wh_per_km(fleet.road_load_b_n_per_m_s * v), "WC": wh_per_km(fleet.road_load_c_n_per_m2_s2 * v**2),
             "WI": wh_per_km(np.broadcast_to(f_inertia, f.shape)),
             "Q": wh_per_km(f**2 / (kw * 1e3)) * 100}
        d |= {"WpM": d["Wp"] * m / 2200, "TP": d["T"] * kw / 300, "Tawd": d["T"] * awd, "WnAwd": d["Wn"] * awd}
        for k, val in d.items():
            out.setdefault(k, []).append(val)
    return {k: np.concatenate(v) for k, v in out.items()}


def linear_cv(feats: dict, y: np.ndarray, cols, groups: np.ndarray) -> tuple[float, np.ndarray]:
    """Grouped-CV mean abs % error of E = sum b_j x_j (least squares on relative error), and b on all rows."""
    X = np.column_stack([feats[c] for c in cols])

    def coef(rows):
        return np.linalg.lstsq(X[rows] / y[rows, None], np.ones(rows.sum()), rcond=None)[0]

    err = np.empty_like(y)
    for g in np.unique(groups):
        test = groups == g
        err[test] = X[test] @ coef(~test) / y[test] - 1
    return 100 * float(np.mean(np.abs(err))), coef(np.ones_like(y, bool))


def _standardise(X_train, X):
    mu, sd = X_train.mean(0), X_train.std(0)
    sd[sd == 0] = 1.0
    return (X - mu) / sd


def ridge_fit_predict(X_tr, t_tr, X_te, alpha):
    Z, Zt = _standardise(X_tr, X_tr), _standardise(X_tr, X_te)
    b = np.linalg.solve(Z.T @ Z + alpha * np.eye(Z.shape[1]), Z.T @ (t_tr - t_tr.mean()))
    return t_tr.mean() + Zt @ b


def knn_fit_predict(X_tr, t_tr, X_te, k=5):
    Z, Zt = _standardise(X_tr, X_tr), _standardise(X_tr, X_te)
    d = ((Zt[:, None, :] - Z[None, :, :]) ** 2).sum(-1)
    return t_tr[np.argsort(d, axis=1)[:, :k]].mean(1)


def residual_cv(X, t, p0, y, groups, inner_groups, learner) -> float:
    """Grouped-CV mean abs % error of p0 exp(learner's prediction of t = log(y / p0))."""
    out = np.empty_like(t)
    for g in np.unique(groups):
        test = groups == g
        out[test] = learner(X[~test], t[~test], X[test], inner_groups[~test])
    return 100 * float(np.mean(np.abs(p0 * np.exp(out) / y - 1)))


def ridge_nested(X_tr, t_tr, X_te, groups_tr, alphas=np.logspace(-3, 4, 15)):
    """Ridge whose penalty is chosen by a family-grouped CV inside the training rows."""
    score = []
    for alpha in alphas:
        e = [np.abs(ridge_fit_predict(X_tr[groups_tr != g], t_tr[groups_tr != g], X_tr[groups_tr == g], alpha)
                    - t_tr[groups_tr == g]) for g in np.unique(groups_tr)]
        score.append(np.mean(np.concatenate(e)))
    return ridge_fit_predict(X_tr, t_tr, X_te, alphas[int(np.argmin(score))])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=None, help="fleet CSV (default: the shipped training file)")
    args = ap.parse_args(argv)
    fleet = fl.read_fleet(args.data)
    keep = ~fleet.outlier
    cycles = fl.resampled_cycles()
    n = len(fleet)
    folds, _ = fl.group_folds(fleet.family(), 5)
    lower = [m.lower() for m in fleet.make]
    makes = np.unique(lower, return_inverse=True)[1]
    fam_ids = np.unique(fleet.family(), return_inverse=True)[1]
    both = np.concatenate
    fold2, lomo2, fam2 = both([folds, folds]), both([makes, makes]), both([fam_ids, fam_ids])
    rows = both([keep, keep])
    y = both([fleet.measured[c] for c in fl.CYCLES])
    feats = work_features(fleet, cycles)

    print("model (mean absolute % error over UDDS + HWFET)            family CV   LOMO CV   note")
    cv_f = cal.cross_validate(fleet, model="chain")["stats"]["mean_abs_pct"]
    cv_m = cal.cross_validate(fleet, 99, groups=lower, model="chain")["stats"]["mean_abs_pct"]
    print(f"{f'shipped chain ({len(cal.FIT)} fitted parameters)':58s} {cv_f:8.2f} {cv_m:9.2f}")

    y_k, f_k = y[rows], {k: v[rows] for k, v in feats.items()}
    fold_k, lomo_k, fam_k = fold2[rows], lomo2[rows], fam2[rows]
    for cols, note in ((("Wp", "Wn"), "traction and regeneration factors"),
                       (("Wp", "Wn", "T"), "+ a constant power, sign free")):
        e_f, b = linear_cv(f_k, y_k, cols, fold_k)
        e_m, _ = linear_cv(f_k, y_k, cols, lomo_k)
        print(f"{'linear in ' + ', '.join(cols):58s} {e_f:8.2f} {e_m:9.2f}   coefficients {np.round(b, 3).tolist()}")
    subsets = [("Wp", "Wn", "T") + extra for r in range(4) for extra in itertools.combinations(EXTRA_TERMS, r)]
    scored = sorted((linear_cv(f_k, y_k, c, fold_k)[0], linear_cv(f_k, y_k, c, lomo_k)[0], c) for c in subsets)
    best = scored[0]
    print(f"{'best of %d linear subsets (picked on family CV: optimistic)' % len(subsets):58s} "
          f"{best[0]:8.2f} {best[1]:9.2f}   {'+'.join(best[2][3:])}")

    base = {**cal.FIXED, **dict(zip(*(lambda f: (f["names"], f["x"]))(cal.fit(fleet, model="chain"))))}
    pred = fl.predict(fleet, "chain", base, cycles)
    p0 = both([pred[c]["energy_wh_per_km"] for c in fl.CYCLES])[rows]
    m, kw = fleet.test_mass_kg, fleet.rated_power_kw
    awd = np.array([d in "A4P" for d in fleet.drive], float)
    cols1 = np.column_stack([np.log(m), fleet.road_load_a_n / (m * 9.81), fleet.road_load_b_n_per_m_s,
                             fleet.road_load_c_n_per_m2_s2, np.log(kw), kw / m, awd, fleet.gear_listed])
    cyc = both([np.zeros(n), np.ones(n)])
    X = np.column_stack([np.vstack([cols1, cols1]), cyc, np.log(feats["Wp"]), feats["Wn"] / feats["Wp"],
                         np.log(feats["Q"])])[rows]
    t = np.log(y_k / p0)
    learners = {"ridge on every column + work features (nested penalty)": ridge_nested,
                "5 nearest neighbours on the same features": lambda a, b, c, g: knn_fit_predict(a, b, c)}
    try:
        from sklearn.ensemble import GradientBoostingRegressor, RandomForestRegressor

        learners["random forest (scikit-learn, 300 trees, leaf >= 3)"] = lambda a, b, c, g: RandomForestRegressor(
            300, min_samples_leaf=3, random_state=0).fit(a, b).predict(c)
        learners["gradient boosting (scikit-learn, depth 2, 200 x 0.05)"] = lambda a, b, c, g: GradientBoostingRegressor(
            n_estimators=200, max_depth=2, learning_rate=0.05, subsample=0.8, random_state=0).fit(a, b).predict(c)
    except ImportError:
        print("(scikit-learn not importable: tree ensembles skipped)")
    for name, learner in learners.items():
        print(f"{name:58s} {residual_cv(X, t, p0, y_k, fold_k, fam_k, learner):8.2f} "
              f"{residual_cv(X, t, p0, y_k, lomo_k, fam_k, learner):9.2f}")
    offset = {g: t[lomo_k == g].mean() for g in np.unique(lomo_k)}
    oracle = 100 * np.mean(np.abs(p0 * np.exp([offset[g] for g in lomo_k]) / y_k - 1))
    print(f"{'oracle: shipped chain x one factor per make (in sample)':58s} {oracle:8.2f} {'':9s}   uses the make name")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
