"""Typed results of the API. Each holds the numbers the CLI's ``--json`` prints (``to_dict()``, JSON-
ready) and a table view (``rows()``, ``to_dataframe()``; pandas is imported only there)."""
from __future__ import annotations

import copy
from dataclasses import dataclass, field
from typing import Any


class _Result:
    data: dict

    def to_dict(self) -> dict:
        """The result as the CLI's JSON holds it: a copy (an edit of it changed the result's own fields)."""
        return copy.deepcopy(self.data)

    def rows(self) -> list[dict]:  # pragma: no cover - every result defines its table
        raise NotImplementedError

    def to_dataframe(self):
        """``rows()`` as a pandas DataFrame (pandas is not a dependency of bev_mdo: install it to use this)."""
        try:
            import pandas as pd
        except ModuleNotFoundError:
            raise ModuleNotFoundError("to_dataframe() needs pandas (pip install pandas); to_dict() and rows() "
                                      "give the same numbers without it") from None
        return pd.DataFrame(self.rows())


def _design_rows(design: dict, outputs: dict, objective: str) -> list[dict]:
    rows = [{"name": k, "value": float(v), "role": "design"} for k, v in design.items()]
    rows += [{"name": k, "value": float(v), "role": "objective" if k == objective else "output"}
             for k, v in outputs.items() if k not in design]
    return rows


@dataclass
class EvaluateResult(_Result):
    """One design through every discipline (``bev-mdo evaluate --json``)."""

    design: dict[str, float]
    outputs: dict[str, float]
    objective_name: str
    objective: float | None
    constraints: dict[str, dict]  # {name: {value, lower, upper, margin, satisfied}}
    feasible: bool
    ok: bool  # every discipline answered
    data: dict = field(repr=False)

    @classmethod
    def of(cls, report: dict) -> "EvaluateResult":
        return cls(report["design"], report["outputs"], report["objective"]["name"], report["objective"]["value"],
                   report["constraints"], bool(report["feasible"]), bool(report["ok"]), report)

    def rows(self) -> list[dict]:
        return _design_rows(self.design, self.outputs, self.objective_name)


@dataclass
class OptimizeResult(_Result):
    """One optimisation (``bev-mdo optimize --json``): ``x`` the design found, ``verdict`` that of the
    first-order check of it (bev_mdo/mdo/first_order.py: "optimum", "stopped before convergence", "no progress
    from the start point" or "infeasible"), ``first_order`` the check itself (active set, multipliers);
    ``to_dict()["active"]`` holds the end-of-run answers (bev_mdo/mdo/active.py)."""

    x: dict[str, float]
    objective_name: str
    objective: float
    outputs: dict[str, float]
    constraints: dict[str, dict]
    feasible: bool
    verdict: str
    first_order: dict
    iterations: int
    data: dict = field(repr=False)

    @classmethod
    def of(cls, doc: dict) -> "OptimizeResult":
        return cls(doc["design"], doc["objective_name"], doc["objective"], doc["outputs"], doc["constraints"],
                   bool(doc["feasible"]), doc["verdict"], doc["first_order"], doc["iterations"], doc)

    @property
    def baseline(self) -> dict | None:
        """The config's ``problem.baseline`` analysed beside the result (None without one)."""
        return self.data.get("baseline")

    def rows(self) -> list[dict]:
        return _design_rows(self.x, self.outputs, self.objective_name)


def _columns(d: dict, i: int) -> dict:
    return {k: float(v[i]) for k, v in d.items()}


@dataclass
class SweepResult(_Result):
    """A batch of designs (a DOE, a grid or a list): one entry per design in every array."""

    design: dict[str, Any]  # {name: array}
    outputs: dict[str, Any]
    margins: dict[str, Any]  # {constraint: array}, positive when satisfied
    feasible: Any  # bool array
    ok: Any  # bool array: every discipline answered
    errors: list
    objective_name: str
    maximize: bool = False

    def rows(self) -> list[dict]:
        """One row per design, the columns of ``bev-mdo sweep``'s sweep.csv."""
        return [{**_columns(self.design, i), **{k: v for k, v in _columns(self.outputs, i).items() if k not in self.design},
                 **{f"margin.{k}": v for k, v in _columns(self.margins, i).items()},
                 "feasible": bool(self.feasible[i]), "ok": bool(self.ok[i]), "error": self.errors[i]}
                for i in range(len(self.feasible))]

    @property
    def data(self) -> dict:
        return {"designs": self.rows(), "objective": self.objective_name, "maximize": self.maximize}

    def best(self) -> dict | None:
        """The row of the best feasible design (None if none is feasible)."""
        rows = [r for r in self.rows() if r["feasible"]]
        pick = max if self.maximize else min
        return pick(rows, key=lambda r: r[self.objective_name]) if rows else None


@dataclass
class SensitivityResult(_Result):
    """Normalised local sensitivities at ``point`` (``bev-mdo sensitivity --json``): ``first_order``
    {output: [one value per wrt]}, ``second_order`` {output: matrix} (order 2)."""

    wrt: list[str]
    point: dict[str, float]
    first_order: dict[str, list[float]]
    second_order: dict[str, list[list[float]]]
    data: dict = field(repr=False)

    @classmethod
    def of(cls, d: dict) -> "SensitivityResult":
        return cls(d["wrt"], d["point"], {k: v["normalised"] for k, v in d["first_order"].items()},
                   {k: v["normalised"] for k, v in d["second_order"].items()}, d)

    def rows(self) -> list[dict]:
        """One row per (output, variable): the normalised first-order value, its error, the derivative."""
        return [{"output": out, "wrt": w, "normalised": f["normalised"][j], "error": f["error"][j],
                 "derivative": f["derivative"][j]}
                for out, f in self.data["first_order"].items() for j, w in enumerate(self.wrt)]


@dataclass
class GlobalSensitivityResult(_Result):
    """Sobol' (S1, ST with confidence intervals) or Morris (mu, mu_star, sigma) indices of every output."""

    method: str
    variables: list[str]
    indices: dict[str, dict]  # {output: {S1: [...], S1_conf: [...], ...}} ({constant: True} for a flat output)
    data: dict = field(repr=False)

    @classmethod
    def of(cls, rep: dict) -> "GlobalSensitivityResult":
        return cls(rep["method"], rep["variables"], rep["outputs"], rep)

    def rows(self) -> list[dict]:
        """One row per (output, variable) with every index of the method."""
        return [{"output": out, "variable": v, **{k: vals[j] for k, vals in ix.items()}}
                for out, ix in self.indices.items() if not ix.get("constant") for j, v in enumerate(self.variables)]


@dataclass
class ParetoResult(_Result):
    """A Pareto front (``front.json`` of ``bev-mdo pareto``): ``front`` one dict per non-dominated
    feasible design, every MDA variable; ``out`` the folder with the bag, CSV and plots."""

    objectives: list[dict]
    front: list[dict]
    out: str
    data: dict = field(repr=False)

    @classmethod
    def of(cls, doc: dict) -> "ParetoResult":
        return cls(doc["objectives"], doc["front"], doc["out"], doc)

    def rows(self) -> list[dict]:
        return self.front
