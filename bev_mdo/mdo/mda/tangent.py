"""Newton's tangent warm start: the couplings of a new point predicted to first order from the
last MDA's converged point, y_ref + dy/dx (x - x_ref), dy/dx = (I - J)^-1 dF/dx at the reference
(J = dF/dy of the loop's last Newton step there, dF/dx the loop disciplines' analytic partials)."""
from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np


def predict(t: tuple | None, values: dict, rows: np.ndarray) -> dict | None:
    """The prediction at ``rows`` from a stored tangent ``t`` (None: not available or not finite)."""
    if t is None:
        return None
    unknowns, xs, x_ref, S, y_ref = t
    dx = np.array([values[x][rows] - x_ref[k] for k, x in enumerate(xs)])  # (nx, n)
    Y = y_ref[:, None] + S @ dx if xs else np.repeat(y_ref[:, None], rows.size, axis=1)
    if not np.isfinite(Y).all():
        return None
    return {v: Y[k] for k, v in enumerate(unknowns)}


def keep_tangent(specs: Mapping, comp: Sequence[str], values: dict, results, J, active, done, converged,
                 col: Mapping[str, int], unknowns: Sequence[str], tangent: dict) -> None:
    """Store in ``tangent`` the tangent at the lowest converged row so far (if it converged in this
    step): {row: (unknowns, xs, x_ref, dy/dx, y_ref)}."""
    first = min(converged)
    where = np.flatnonzero(active == first)
    if not where.size or not done[where[0]]:
        return
    q = where[0]
    xs = sorted({i for m in comp for i in specs[m].inputs if i not in col}
                | {p for m in comp for p in specs[m].parameters if p in values})
    xi = {x: k for k, x in enumerate(xs)}
    dF = np.zeros((len(unknowns), len(xs)))
    for res in results:
        for (o, i), c in res.extra.get("partials", {}).items():
            if o in col and i in xi:
                dF[col[o], xi[i]] = np.asarray(c)[q]
    try:
        S = np.linalg.solve(np.eye(len(unknowns)) - J[q], dF)
    except np.linalg.LinAlgError:
        return
    tangent.clear()
    tangent[first] = (list(unknowns), xs, np.array([values[x][first] for x in xs]), S,
                      np.array([values[v][first] for v in unknowns]))
