"""Data-flow evaluation of a feed-forward graph: one request for a whole MDA.

Every discipline of an acyclic graph gets the same request (the design variables and
parameter columns of N points). A discipline takes each coupling input from the result of
the discipline that produces it (its *source*) and every other input from the request. It
evaluates the points that all its sources evaluated successfully; the other points are
failed without a message of their own (the source's error names them). Point errors
(``EvalResult.point_errors``) are keyed by the index in the whole batch.

The rule is the same everywhere it runs: ``flow_by_waves`` (any evaluator, one wave per graph
level, used in process: ``InProcessEvaluator.evaluate_flow``), and the discipline nodes over ROS
(one request message for the whole MDA, results passed from node to node; a node joins its
sources' results with ``FlowJoin`` and evaluates with ``run_flow_discipline``). So both
transports evaluate the same rows with the same inputs and count the same evaluations.
"""
from __future__ import annotations

from collections import OrderedDict
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from bev_mdo.mdo.discipline import EvalResult, failed, rejected, run_discipline, spread, unknown_inputs

Upstream = Mapping[str, tuple[Mapping[str, np.ndarray], np.ndarray]]  # source -> (outputs, ok)


def sources_of(inputs: Sequence[str], producer: Mapping[str, str], name: str) -> dict[str, str]:
    """input -> the other discipline producing it (only inputs some other discipline produces)."""
    return {v: producer[v] for v in inputs if v in producer and producer[v] != name}


def flow_inputs(inputs: Sequence[str], parameters: Sequence[str], request: Mapping[str, np.ndarray],
                upstream: Upstream, source_of: Mapping[str, str], n: int) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """(batch of the rows to evaluate, their indices) for one discipline of a data-flow request.

    Raises KeyError naming an input that is neither in the request nor in a source's outputs."""
    rows = source_rows(source_of, upstream, n)
    if not rows.any():
        return {}, np.zeros(0, dtype=int)
    cols = {}
    for v in inputs:
        s = source_of.get(v)
        cols[v] = upstream[s][0][v] if s is not None else request[v]
    for p in parameters:
        if p in request and p not in cols:
            cols[p] = request[p]
    if rows.all():
        return cols, np.arange(n)
    idx = np.flatnonzero(rows)
    return {k: np.asarray(c)[idx] for k, c in cols.items()}, idx


def scatter(res: EvalResult, idx: np.ndarray, n: int, outputs: Sequence[str]) -> EvalResult:
    """An EvalResult over all n rows from one over the rows ``idx`` (others failed, NaN)."""
    if idx.size == n:
        return res
    out = {k: spread(res.outputs[k], idx, n) for k in outputs}
    ok = np.zeros(n, dtype=bool)
    ok[idx] = res.ok
    extra = dict(res.extra)
    if "partials" in extra:
        extra["partials"] = {k: spread(col, idx, n) for k, col in extra["partials"].items()}
    return EvalResult(out, ok, res.error, res.compute_time_s, extra, res.point_errors)


def run_flow_discipline(disc: Any, request: Mapping[str, np.ndarray], upstream: Upstream,
                        source_of: Mapping[str, str], n: int, partials: bool = False) -> tuple[EvalResult, int]:
    """Evaluate ``disc`` for one data-flow request; returns (result over all n rows, rows evaluated)."""
    batch, idx = flow_inputs(disc.inputs, tuple(getattr(disc, "parameters", {}) or {}), request, upstream,
                             source_of, n)
    if idx.size == 0:
        return failed(disc.outputs, n), 0
    res = run_discipline(disc, batch, partials)
    if idx.size != n:
        res = res.renumbered(idx)
    return scatter(res, idx, n, disc.outputs), int(idx.size)


def source_rows(source_of: Mapping[str, str], upstream: Upstream, n: int) -> np.ndarray:
    """The rows a discipline evaluates: those every one of its sources evaluated successfully."""
    rows = np.ones(n, dtype=bool)  # a root evaluates every row
    for s in set(source_of.values()):
        rows &= np.asarray(upstream[s][1], dtype=bool)
    return rows


def flow_by_waves(evaluator: Any, specs: Mapping[str, Any], waves: Sequence[Sequence[str]],
                  request: Mapping[str, np.ndarray], n: int, partials: bool = False) -> dict[str, EvalResult]:
    """The data-flow rule over any evaluator: one ``evaluate`` call per wave of the graph."""
    producer = {v: name for name in specs for v in specs[name].outputs}
    results: dict[str, EvalResult] = {}
    for wave in waves:
        calls, plan = [], []
        for name in wave:
            spec = specs[name]
            src = sources_of(spec.inputs, producer, name)
            up = {s: (results[s].outputs, results[s].ok) for s in set(src.values())}
            batch, idx = flow_inputs(spec.inputs, tuple(spec.parameters), request, up, src, n)
            if idx.size == 0:
                results[name] = failed(spec.outputs, n)
                continue
            calls.append((name, batch))
            plan.append((name, idx))
        if not calls:
            continue
        got = evaluator.evaluate(calls, partials=True) if partials else evaluator.evaluate(calls)
        for (name, idx), res in zip(plan, got):
            res = res.renumbered(idx) if idx.size != n else res
            results[name] = scatter(res, idx, n, specs[name].outputs)
    return results


def evaluate_flow(evaluator: Any, specs: Mapping[str, Any], waves: Sequence[Sequence[str]],
                  request: Mapping[str, np.ndarray], n: int, partials: bool = False) -> dict[str, EvalResult]:
    """One data-flow MDA: the evaluator's own ``evaluate_flow`` (one request) when it offers one
    and can serve these disciplines that way, else :func:`flow_by_waves`. With ``partials`` every
    discipline that has analytic partials returns them with its result. A request column that no
    discipline of the MDA reads fails every point, named (as a node refuses an unknown input)."""
    names = [name for wave in waves for name in wave]
    allowed = frozenset().union(*(specs[m].inputs for m in names), *(specs[m].parameters for m in names))
    unknown = unknown_inputs(allowed, request)
    if unknown:  # the entry check of every transport (discipline.unknown_inputs): refused, not dropped
        return {m: rejected(m, specs[m].outputs, n, f"unknown inputs {unknown[:5]}") for m in names}
    own = getattr(evaluator, "evaluate_flow", None)
    if own is not None:
        got = own(names, request, n, partials=True) if partials else own(names, request, n)
        if got is not None:
            return got
    return flow_by_waves(evaluator, specs, waves, request, n, partials)


def rows_per_discipline(plan: Mapping[str, Mapping[str, str]], results: Mapping[str, EvalResult], n: int,
                        names: Sequence[str]) -> dict[str, int]:
    """{discipline: rows it evaluated} of a data-flow MDA of `n` rows, for each of `names` that
    evaluated any (the rows all its sources evaluated: the coordinator's count after the MDA)."""
    out = {}
    for name in names:
        up = {s: (results[s].outputs, results[s].ok) for s in set(plan[name].values())}
        rows = int(np.count_nonzero(source_rows(plan[name], up, n)))
        if rows:
            out[name] = rows
    return out


class FlowError(ValueError):
    """A source's result that cannot take part in a data-flow MDA (malformed: not kept)."""


class SourcesDisagree(FlowError):
    """The sources of one data-flow MDA answered different numbers of points."""


@dataclass
class Joined:
    """Everything one discipline needs to evaluate its share of a data-flow MDA, once every one of
    its sources (in that MDA) has answered: ``run_flow_discipline(disc, request, up, sources, n)``."""

    request: dict[str, np.ndarray]   # the request's columns, forwarded by the sources
    up: dict[str, tuple[Mapping[str, np.ndarray], np.ndarray]]  # source -> (outputs, ok over n rows)
    sources: dict[str, str]          # coupling input -> its source, in this MDA
    n: int
    extras: dict[str, Any]           # source -> what the transport attached to its result
    rejected: tuple[str, ...] = ()   # sources that rejected the request (evaluated nothing)


class _Got(NamedTuple):
    """One source's result kept by FlowJoin until the MDA's other sources answer."""

    columns: Mapping[str, np.ndarray]
    ok: np.ndarray
    extra: Any
    rejected: bool


class FlowJoin:
    """The join of a discipline's sources' results, per data-flow MDA: wherever the results come
    from (the ROS nodes' mda_result topics, or direct calls in a composed process). Keeps at most
    ``keep`` unfinished MDAs (the oldest is forgotten: a lost MDA is re-sent by the coordinator)."""

    def __init__(self, source_of: Mapping[str, str], outputs_of: Mapping[str, set[str]], keep: int = 64):
        self.source_of = dict(source_of)   # coupling input -> source discipline
        self.outputs_of = {s: set(v) for s, v in outputs_of.items()}  # source -> every output it produces
        self.keep = keep
        self._coupling_of: dict[str, list[str]] = {}  # source -> the coupling inputs it feeds (checked per result)
        for v, s in self.source_of.items():
            self._coupling_of.setdefault(s, []).append(v)
        self._got: OrderedDict[Any, dict[str, _Got]] = OrderedDict()

    def add(self, key: Any, source: str, columns: Mapping[str, np.ndarray], ok: np.ndarray,
            flow_names: Sequence[str], rejected: bool = False, extra: Any = None, n: int | None = None
            ) -> Joined | None:
        """Keep ``source``'s result for the MDA ``key`` (``columns``: its outputs and the request's
        columns it forwards, ``n`` rows each; ``rejected``: it evaluated nothing); the join once every
        source of this discipline taking part in the MDA (``flow_names``) has answered, else None.
        FlowError for a malformed result (not kept); SourcesDisagree when the sources' batch sizes
        differ (the MDA is then forgotten here)."""
        ok = np.asarray(ok, dtype=bool)
        if rejected:  # nothing to evaluate downstream of it
            columns, ok = {}, np.zeros(0, dtype=bool)
        else:
            n = len(ok) if n is None else n
            if ok.shape != (n,) or any(v not in columns for v in self._coupling_of.get(source, ())) or any(
                    (c.shape if type(c) is np.ndarray else np.shape(c)) != (n,) for c in columns.values()):
                raise FlowError(f"result of {source!r} misses a coupling column or has rows of another size")
        got = {**self._got.get(key, {}), source: _Got(columns, ok, extra, rejected)}
        self._got[key] = got
        self._got.move_to_end(key)
        while len(self._got) > self.keep:
            self._got.popitem(last=False)
        sources = {v: s for v, s in self.source_of.items() if s in flow_names}
        if any(s not in got for s in sources.values()):
            return None
        del self._got[key]
        sizes = {g.ok.size for g in got.values() if g.ok.size}
        if len(sizes) > 1:
            raise SourcesDisagree("sources answered different numbers of points")
        n = sizes.pop() if sizes else 0
        request: dict[str, np.ndarray] = {}
        for s, g in got.items():  # the request's columns, forwarded by each source
            request.update({k: v for k, v in g.columns.items() if k not in self.outputs_of.get(s, ())})
        up = {s: (g.columns, g.ok if g.ok.size else np.zeros(n, bool)) for s, g in got.items()}
        return Joined(request, up, sources, n, {s: g.extra for s, g in got.items()},
                      tuple(sorted(s for s, g in got.items() if g.rejected)))

    def __len__(self) -> int:
        return len(self._got)
