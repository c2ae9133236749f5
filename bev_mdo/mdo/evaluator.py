"""The transport seam between the MDO engine and the disciplines.

An evaluator runs *one wave* of discipline calls at a time::

    results = evaluator.evaluate([("vehicle_mass", {"motor_kw": X0, "battery_kwh": X1}),
                                  ("motor_speed", {"gear_ratio": X2})])

Each call carries a batch (arrays of shape (N,), N may differ between calls).
The calls of one wave are independent, so an implementation may run them
concurrently; it returns one ``EvalResult`` per call, in call order, and never
raises for a failed point (those rows have ``ok`` False, NaN outputs and an
error text). ``InProcessEvaluator`` runs them here; the ROS evaluator sends
them to the discipline nodes.
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

from bev_mdo.mdo.discipline import EvalResult, readable, rejected, run_discipline, unknown_inputs
from bev_mdo.mdo.flow import flow_by_waves
from bev_mdo.mdo.graph import CouplingGraph
from bev_mdo.mdo.vectors import has_partials


@dataclass(frozen=True)
class DisciplineSpec:
    """What a discipline declares: its inputs, outputs and overridable parameters (with defaults)."""

    name: str
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    parameters: Mapping[str, float] = field(default_factory=dict)
    partials: bool | None = None  # provides analytic partials (None: not known to this transport)

    @classmethod
    def of(cls, disc: Any) -> "DisciplineSpec":
        name = getattr(disc, "name", "") or type(disc).__name__
        return cls(str(name), tuple(disc.inputs), tuple(disc.outputs),
                   dict(getattr(disc, "parameters", {}) or {}), has_partials(disc))


Call = tuple[str, Mapping[str, np.ndarray]]


@runtime_checkable
class Evaluator(Protocol):
    """Interface every transport implements (in-process here, ROS in bev_mdo.ros)."""

    specs: dict[str, DisciplineSpec]   # discipline name -> declaration
    counts: dict[str, int]             # discipline name -> points evaluated so far

    def evaluate(self, calls: list[Call]) -> list[EvalResult]:
        """Run one wave of independent batched calls; results in call order.

        Called as ``evaluate(calls, partials=True)`` it also asks each discipline for its
        analytic partials (``EvalResult.extra["partials"]``, absent if it has none)."""
        ...

    def evaluate_flow(self, names: Sequence[str], request: Mapping[str, np.ndarray], n: int,
                      partials: bool = False) -> dict[str, EvalResult] | None:
        """One feed-forward MDA of ``names`` (topological order) over ``request`` (n rows) by the
        data-flow rule (flow.py): {discipline: result over all n rows}; None when this transport
        cannot serve these disciplines that way (the caller then goes wave by wave)."""
        ...

    def close(self) -> None:
        """Release resources (processes, nodes); idempotent."""
        ...


class DisciplinesLost(Exception):
    """Disciplines were declared unresponsive (``unresponsive``): raised into a running optimiser
    (Formulation.stop_on_lost) to stop it, as every later point of theirs would fail at once."""

    def __init__(self, names: Sequence[str]):
        self.names = list(names)
        super().__init__(", ".join(self.names))


def unresponsive(evaluator: Any) -> list[str]:
    """The disciplines ``evaluator`` declared unresponsive for the rest of the run (the ROS orchestrator: every
    attempt of a request timed out and no restart came back; in process: a call overran its budget, mdo/timed.py);
    [] for a transport that never declares one."""
    return sorted(getattr(evaluator, "unresponsive", ()) or ())


class InProcessEvaluator:
    """Evaluator that calls the discipline objects directly, one after the other."""

    def __init__(self, disciplines: Iterable[Any]):
        self.disciplines, self.specs = {}, {}
        for d in disciplines:
            spec = DisciplineSpec.of(d)
            if spec.name in self.specs:
                raise ValueError(f"discipline name {spec.name!r} is used twice; names must be unique")
            self.disciplines[spec.name] = d
            self.specs[spec.name] = spec
        self.counts = {n: 0 for n in self.disciplines}
        self.waves = 0  # number of evaluate() calls (request waves)
        self._readable = {n: readable(d) for n, d in self.disciplines.items()}
        self._flow_waves: dict[tuple, list | None] = {}  # names -> their graph's waves (None: a loop)

    def evaluate(self, calls: list[Call], partials: bool = False) -> list[EvalResult]:
        self.waves += 1
        results = []
        for name, inputs in calls:
            if name not in self.disciplines:
                raise ValueError(f"unknown discipline {name!r}; known: {sorted(self.disciplines)}")
            unknown = unknown_inputs(self._readable[name], inputs)
            if unknown:  # refused as a node refuses it: every point failed, named
                n = len(next(iter(inputs.values())))
                res = rejected(name, self.specs[name].outputs, n, f"unknown inputs {unknown[:5]}")
            else:
                res = run_discipline(self.disciplines[name], inputs, partials)
            self.counts[name] += int(np.size(res.ok))
            results.append(res)
        return results

    def evaluate_flow(self, names: Sequence[str], request: Mapping[str, np.ndarray], n: int,
                      partials: bool = False) -> dict[str, EvalResult] | None:
        """The data-flow rule wave by wave (flow.flow_by_waves): the same rows, inputs and counts as
        the ROS nodes' one-request data flow. None for a graph with a loop."""
        key = tuple(names)
        waves = self._flow_waves.get(key)
        if waves is None:
            graph = CouplingGraph((m, self.specs[m].inputs, self.specs[m].outputs) for m in names)
            waves = None if graph.cycles else [[c[0] for c in wave] for wave in graph.waves]
            self._flow_waves[key] = waves
        if waves is None:
            return None
        return flow_by_waves(self, {m: self.specs[m] for m in names}, waves, request, n, partials)

    @property
    def unresponsive(self) -> list[str]:
        """The disciplines that overran their time budget (mdo/timed.py): hung for the rest of the run."""
        return sorted(n for n, d in self.disciplines.items() if getattr(d, "hung", False))

    def close(self) -> None:
        pass
