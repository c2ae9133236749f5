"""Coupling graph of disciplines built from their declared inputs and outputs.

An edge A -> B means B consumes an output of A. Strongly connected components
(feedback loops) are found with scipy's Tarjan-style ``connected_components``,
put in topological order, and grouped into *waves*: components of one wave do
not depend on each other, so they may run concurrently.
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from bev_mdo.mdo.vectors import base_name, did_you_mean

Spec = tuple[str, Sequence[str], Sequence[str]]


class CouplingGraph:
    """Dependency graph of named disciplines.

    ``specs`` are (name, inputs, outputs). Attributes after construction:
    ``names`` (declared order), ``producer`` (output -> discipline),
    ``external_inputs`` (inputs no discipline produces), ``components``
    (list of tuples of names, topological order), ``waves`` (list of lists of
    components), ``couplings`` (outputs consumed by some discipline).
    Raises ValueError when an output is produced twice.
    """

    def __init__(self, specs: Iterable[Spec]):
        specs = [(str(n), tuple(i), tuple(o)) for n, i, o in specs]
        self.names = [n for n, _, _ in specs]
        if len(set(self.names)) != len(self.names):
            dup = sorted({n for n in self.names if self.names.count(n) > 1})
            raise ValueError(f"discipline names {dup} are used twice; each discipline needs a unique name")
        self.inputs = {n: i for n, i, _ in specs}
        self.outputs = {n: o for n, _, o in specs}
        self.producer: dict[str, str] = {}
        for name, _, outs in specs:
            for var in outs:
                if var in self.producer:
                    raise ValueError(
                        f"output {var!r} is produced by both {self.producer[var]!r} and {name!r}; "
                        "each variable must have exactly one producer")
                self.producer[var] = name
        consumed = {v for i in self.inputs.values() for v in i}
        self.external_inputs = sorted(consumed - set(self.producer))
        self.couplings = sorted(consumed & set(self.producer))
        self._build_order()

    def _build_order(self) -> None:
        idx = {n: k for k, n in enumerate(self.names)}
        n = len(self.names)
        rows, cols = [], []
        for b in self.names:
            for var in self.inputs[b]:
                a = self.producer.get(var)
                if a is not None:
                    rows.append(idx[a])
                    cols.append(idx[b])
        self.self_loops = {self.names[r] for r, c in zip(rows, cols) if r == c}
        adj = csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
        ncomp, labels = connected_components(adj, directed=True, connection="strong") if n else (0, [])
        comps: list[list[str]] = [[] for _ in range(ncomp)]
        for k, lab in enumerate(labels):
            comps[lab].append(self.names[k])  # keeps declared order inside a loop
        deps: list[set[int]] = [set() for _ in range(ncomp)]
        for r, c in zip(rows, cols):
            if labels[r] != labels[c]:
                deps[labels[c]].add(labels[r])
        level = [-1] * ncomp

        def depth(c: int) -> int:
            if level[c] < 0:
                level[c] = 1 + max((depth(d) for d in deps[c]), default=-1)
            return level[c]

        first = [min(idx[m] for m in comps[c]) for c in range(ncomp)]
        order = sorted(range(ncomp), key=lambda c: (depth(c), first[c]))
        self.components = [tuple(comps[c]) for c in order]
        nwaves = 1 + max(level, default=-1)
        self.waves = [[tuple(comps[c]) for c in order if level[c] == w] for w in range(nwaves)]

    def is_cyclic(self, component: Sequence[str]) -> bool:
        """True for a feedback loop (several disciplines, or one that consumes its own output)."""
        return len(component) > 1 or component[0] in self.self_loops

    @property
    def cycles(self) -> list[tuple[str, ...]]:
        return [c for c in self.components if self.is_cyclic(c)]

    def check_inputs(self, available: Iterable[str]) -> None:
        """Raise ValueError naming inputs that nobody produces and that are not in ``available``: the first
        discipline's, with every other discipline's (a topology's motor_rear_kw and gear_ratio_rear came one
        error at a time). A nearest name is suggested among the names the discipline does not read already:
        'motor_rear_kw' got "did you mean 'motor_kw'?", another of its inputs, not a misspelling."""
        avail = set(available)
        lacking = {name: miss for name in self.names
                   if (miss := [v for v in self.inputs[name] if v not in self.producer and v not in avail])}
        if not lacking:
            return
        (name, missing), *others = lacking.items()
        known = {base_name(v) for v in [*self.producer, *avail]} - {base_name(v) for v in self.inputs[name]}
        hints = [f"{v!r} is a vector of {k} elements (discipline {self.producer[f'{v}[0]']!r}): add "
                 f"shapes = {{{v!r}: {k}}} to {name!r}" if (k := sum(1 for p in self.producer if p.startswith(f"{v}[")))
                 else did_you_mean(v, known).strip() for v in dict.fromkeys(map(base_name, missing))]
        hint = "; ".join(h for h in hints if h)
        also = "; ".join(f"{n!r} needs {m}" for n, m in others)
        raise ValueError(f"discipline {name!r} needs {missing}, which no discipline produces and which are not "
                         "design variables or parameters" + (f" ({hint})" if hint else "")
                         + (f"; also {also}" if also else ""))

    def torn_inputs(self, component: Sequence[str]) -> list[str]:
        """Coupling variables a Gauss-Seidel sweep of ``component`` (in its order) reads before they are computed."""
        done: set[str] = set()
        inside = {v for m in component for v in self.outputs[m]}
        torn: list[str] = []
        for m in component:
            for v in self.inputs[m]:
                if v in inside and v not in done and v not in torn:
                    torn.append(v)
            done.update(self.outputs[m])
        return torn
