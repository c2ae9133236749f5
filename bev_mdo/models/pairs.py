"""Within-family pairs of a fleet: does a model move with the design as measured cars do?

A pair is two vehicles of one model line (``Fleet.model_line``: make + model name, split by pack
voltage class where the file gives it) that differ in drive (two-wheel against all-wheel, front
against rear), rated power or test mass; rows that differ only in wheels or trim (same drive,
power and mass) are not a pair. Each pair (A = the earlier row, B = the later one) is compared by
its percentage difference from the pair's mean, ``200 (E_B - E_A) / (E_A + E_B)``, measured and
predicted: it changes sign, not size, when A and B swap, so no figure depends on the file's row
order (``100 (E_B / E_A - 1)`` moved the slope and the mean difference by up to 0.3 points when
the same rows were reversed). :func:`pair_stats` gives the slope
of predicted on measured by least squares through the origin and the mean absolute difference
between them in percentage points. Pure numpy; used by ``bev-mdo validate --pairs``.
"""
from __future__ import annotations

import numpy as np

# Targets for a model offered for optimisation (docs/validation.md).
SLOPE_TARGET = (0.85, 1.15)
MEAN_ABS_DIFF_TARGET_POINTS = 2.5
# EPA drive codes: F front, R rear, A/4/P all-wheel (one class)
_DRIVE_CLASS = {"F": "F", "R": "R", "A": "AWD", "4": "AWD", "P": "AWD"}


def drive_class(code: str) -> str:
    """F, R or AWD from an EPA drive code ('' when the file leaves it empty)."""
    return _DRIVE_CLASS.get(code.strip().upper(), code.strip().upper())


def find_pairs(family, drive, rated_power_kw, test_mass_kg, usable=None) -> list[tuple[int, int]]:
    """Every (a, b), a < b, of rows in one family that differ in drive class, rated power or test
    mass; rows with ``usable`` False (outliers) take no part."""
    n = len(family)
    usable = np.ones(n, bool) if usable is None else np.asarray(usable, bool)
    spec = [(drive_class(drive[i]), round(float(rated_power_kw[i]), 3), round(float(test_mass_kg[i]), 3))
            for i in range(n)]
    return [(a, b) for a in range(n) for b in range(a + 1, n)
            if usable[a] and usable[b] and family[a] == family[b] and spec[a] != spec[b]]


def pct_diff(energy: np.ndarray, pairs: list[tuple[int, int]]) -> np.ndarray:
    """200 (E_B - E_A) / (E_A + E_B) for each pair: percent of the pair's mean, antisymmetric."""
    e = np.asarray(energy, float)
    return np.array([200.0 * (e[b] - e[a]) / (e[a] + e[b]) for a, b in pairs])


def pair_stats(measured_pct: np.ndarray, predicted_pct: np.ndarray) -> dict:
    """Slope of predicted on measured (least squares through the origin, sum(x y) / sum(x^2)),
    mean absolute difference in points, and whether the targets are met (None without pairs)."""
    x, y = np.asarray(measured_pct, float), np.asarray(predicted_pct, float)
    n = int(x.size)
    if n == 0 or not np.any(x):
        slope = None
    else:
        slope = float(np.dot(x, y) / np.dot(x, x))
    mad = float(np.mean(np.abs(y - x))) if n else None
    slope_met = None if slope is None else bool(SLOPE_TARGET[0] <= slope <= SLOPE_TARGET[1])
    mad_met = None if mad is None else bool(mad <= MEAN_ABS_DIFF_TARGET_POINTS)
    return {"n": n, "slope_through_origin": slope, "mean_abs_diff_points": mad,
            "slope_target": list(SLOPE_TARGET), "mean_abs_diff_target_points": MEAN_ABS_DIFF_TARGET_POINTS,
            "slope_met": slope_met, "mean_abs_diff_met": mad_met,
            "targets_met": None if slope_met is None or mad_met is None else slope_met and mad_met}
