"""The discipline interface: named batched inputs in, named batched outputs out.

A discipline is any class with ``name``, ``inputs``, ``outputs`` and
``compute(inputs) -> outputs`` where every value is a float64 array of shape (N,).
It is stateless per call, so retries and duplicate instances are safe.

Vector variables: ``shapes = {name: size}`` (see vectors.py). Analytic partial derivatives:
an optional ``compute_partials(inputs) -> {(output, input): array (N, out_size, in_size)}``
next to ``compute`` (see docs/derivatives.md); ``run_discipline(..., partials=True)`` returns
them flattened in ``EvalResult.extra["partials"]``.

``units = {name: unit}`` declares the unit of every input and output (units.py): a consumer whose
unit differs from the producer's gets its inputs converted on entry (``unit_conversions``, set at
load by config.resolve_disciplines), here, on every transport.

``parameters`` lists model constants that a caller may override per point by
sending an input column of the same name (used for sensitivities with respect
to model parameters, e.g. ``drag_area_m2``).

Options (the ``options:`` of a config entry) are declared once, and a key not declared is refused
when the config is loaded (user_class.py: ``read_options``, and ``load_class`` for a user's own class).
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from bev_mdo.mdo.vectors import ShapeError, check_outputs, flat_partials, has_partials, rejection

Batch = dict[str, np.ndarray]


class DisciplineError(ValueError):
    """A discipline could not evaluate some points; the message names it and the inputs."""


class Discipline:
    """Base class for disciplines (subclassing it is optional: duck typing is enough)."""

    name: str = ""
    inputs: tuple[str, ...] = ()
    outputs: tuple[str, ...] = ()
    units: Mapping[str, str] = {}  # {input or output: unit}, e.g. {"range_km": "km", "gear_ratio": "1"}
    parameters: Mapping[str, float] = {}

    @classmethod
    def from_config(cls, config: Mapping[str, Any], options: Any) -> "Discipline":
        """Build from the resolved run config and the entry's options (:func:`read_options`); the
        default passes the options to the constructor as keyword arguments."""
        return cls(**options_dict(options))

    def prepare(self) -> None:
        """Optional one-time work (compiling a model, loading a table), run by :func:`prepare`."""

    def compute(self, inputs: Batch) -> Batch:  # pragma: no cover - interface
        raise NotImplementedError


def prepare(disc: Any) -> None:
    """Run a discipline's optional ``prepare()`` once, before its first timed call in process and before a
    node serves it, so that a slow start (a model compiling) is not taken for a hang."""
    getattr(disc, "prepare", lambda: None)()


def options_dict(options: Any) -> dict:
    """A discipline's options as a plain dict (from an ``Options`` instance or a mapping)."""
    return dataclasses.asdict(options) if dataclasses.is_dataclass(options) else dict(options or {})


@dataclass(frozen=True)
class PointError:
    """Why one point of a call failed: the discipline's reason and that point's inputs.

    The point's index is not part of it (it is the key of ``EvalResult.point_errors``), so a
    result cut into shares or scattered into a larger batch is renumbered by its keys alone."""

    reason: str       # e.g. "square: ValueError: x must be >= 0"
    inputs: str = ""  # e.g. "x=-1, z=0" (empty: not known)

    def text(self, point: int) -> str:
        """The message naming the point: ``reason at point i (inputs)``."""
        return f"{self.reason} at point {point}" + (f" ({self.inputs})" if self.inputs else "")


PointErrors = dict[int, PointError]  # point index (into the call's batch) -> why it failed


def error_text(point_errors: Mapping[int, PointError]) -> str:
    """The human-readable error of a call from its point errors (in their order)."""
    return "; ".join(e.text(i) for i, e in point_errors.items())


@dataclass
class EvalResult:
    """Outputs of one discipline call; rows that failed hold NaN.

    A failed point is named in ``point_errors`` (its index -> why); ``error`` is the text for
    people (logs, console, the result message), never read back. A call that failed as a whole
    (no answer, a rejected request) has ``error`` and no point errors."""

    outputs: Batch
    ok: np.ndarray  # bool (N,)
    error: str = ""
    compute_time_s: float = 0.0
    extra: dict = field(default_factory=dict)  # e.g. "partials": analytic derivatives, see the module doc
    point_errors: PointErrors = field(default_factory=dict)

    def message(self, local: int, point: int, name: str) -> str:
        """Why row ``local`` of this result failed, naming it as point ``point`` of the caller's batch."""
        e = self.point_errors.get(local)
        return e.text(point) if e is not None else (self.error or f"{name}: failed")

    def renumbered(self, idx: np.ndarray) -> "EvalResult":
        """The same result with row i's point errors moved to point ``idx[i]`` (a sub-batch placed
        in a larger one); the error text follows."""
        if not self.point_errors:
            return self
        pe = {int(idx[i]): e for i, e in self.point_errors.items()}
        return EvalResult(self.outputs, self.ok, error_text(pe), self.compute_time_s, self.extra, pe)


def join_errors(parts: Iterable[tuple[int, EvalResult]]) -> tuple[str, PointErrors]:
    """(error text, point errors) of results over consecutive row ranges, each given with its
    first row in the joined batch; repeated call-level texts are named once."""
    texts: list[str] = []
    joined: PointErrors = {}
    for start, r in parts:
        if r.point_errors:
            pe = {start + i: e for i, e in r.point_errors.items()}
            joined.update(pe)
            texts.append(error_text(pe))
        elif r.error:
            texts.append(r.error)
    return "; ".join(dict.fromkeys(texts)), joined


def _batch_size(batch: Mapping[str, np.ndarray]) -> int:
    sizes = {v.shape[0] for v in batch.values()}  # 1-D columns (_column)
    if len(sizes) > 1:
        raise DisciplineError(f"input arrays have different lengths {sorted(sizes)}")
    return sizes.pop() if sizes else 0


def describe_row(inputs: Mapping[str, np.ndarray], i: int) -> str:
    """Row `i` of `inputs` for a message naming a point: ``motor_kw=88, gear_ratio=8``."""
    return ", ".join(f"{k}={float(v[i]):.6g}" for k, v in inputs.items())


def readable(disc: Any) -> frozenset[str]:
    """The names a request may give ``disc``: its inputs and its parameters."""
    return frozenset(disc.inputs) | frozenset(getattr(disc, "parameters", None) or ())


def unknown_inputs(allowed: frozenset[str], columns: Iterable[str]) -> list[str]:
    """The columns of a request that a discipline does not read (``allowed``: ``readable(disc)``).
    The entry check every transport applies the same way: a request naming one is rejected, its
    points failed with ``<name>: rejected: unknown inputs [...]`` (over ROS by the node, in process
    by InProcessEvaluator), never silently dropped."""
    return [k for k in columns if k not in allowed]


def first_error_line(error: str, limit: int = 300) -> str:
    """The line that names a discipline's failure on the console: the error's first line, cut at the
    last whole point's message ("; " parts) within ``limit`` characters, not inside a word."""
    line = error.strip().splitlines()[0] if error.strip() else ""
    if len(line) <= limit:
        return line
    cut = line.rfind("; ", 0, limit)
    return (line[:cut] if cut > 0 else line[:limit]) + " ..."


def failed(outputs: Sequence[str], n: int, error: str = "") -> EvalResult:
    """Every point of a call failed: NaN outputs, `error` saying why (a refused request, a request
    never answered, rows a data-flow discipline had no inputs for)."""
    return EvalResult({k: np.full(n, np.nan) for k in outputs}, np.zeros(n, dtype=bool), error)


def rejected(name: str, outputs: Sequence[str], n: int, why: str) -> EvalResult:
    """The result of a request a discipline refused: every point failed, the reason named."""
    return failed(outputs, n, rejection(name, why))


def run_discipline(disc: Any, inputs: Mapping[str, Any], partials: bool = False) -> EvalResult:
    """Validate inputs, call ``disc.compute`` on the batch and validate its outputs.

    Never raises for a model failure: a batch that raises is retried point by point,
    and every point that raises or gives NaN/Inf is marked failed with NaN outputs
    and named (with its inputs) in ``EvalResult.point_errors``. Missing inputs raise
    DisciplineError because that is a wiring mistake, not a bad point; so does an output or
    partial of the wrong shape (vectors.ShapeError, naming the discipline).

    With ``partials`` and a discipline that provides them, ``extra["partials"]`` holds
    {(output, input): (N,)} at the evaluated inputs (NaN on failed points).
    """
    name = getattr(disc, "name", type(disc).__name__)
    missing = [k for k in disc.inputs if k not in inputs]
    if missing:
        raise DisciplineError(f"discipline {name!r} is missing inputs {missing}")
    params = getattr(disc, "parameters", None) or ()
    batch = {k: _column(v) for k, v in inputs.items() if k in disc.inputs or k in params}
    conv = getattr(disc, "unit_conversions", None)  # {input: (scale, offset)} set at load (units.py)
    shown = batch  # what an error names: the run's values, in the run's units
    if conv:
        shown = {k: v.copy() if k in conv else v for k, v in batch.items()}
        for k, (scale, offset) in conv.items():
            batch[k] *= scale  # batch columns are this call's own copies (_column)
            if offset:
                batch[k] += offset
    n = _batch_size(batch)
    t0 = time.perf_counter()
    if n == 0:  # a batch of no point (a transport's probe or warm-up): nothing to compute
        return EvalResult({k: np.zeros(0) for k in disc.outputs}, np.zeros(0, dtype=bool))
    # the common case first: every input finite, compute() succeeds, every output finite
    bad_in = None if all_finite(batch.values()) else ~finite_rows(list(batch.values()), n)
    try:
        if bad_in is not None and bad_in.any():
            raise DisciplineError("non-finite inputs")
        out = _call(disc, batch, n)
    except ShapeError:
        raise
    except Exception:
        out = None
    if out is not None:
        if all_finite([out[k] for k in disc.outputs]):
            res = EvalResult(out, np.ones(n, dtype=bool), "", time.perf_counter() - t0)
            return _with_partials(disc, batch, res, n, t0) if partials else res
        finite = finite_rows([out[k] for k in disc.outputs], n)
    if bad_in is None:
        bad_in = np.zeros(n, dtype=bool)
    ok = np.ones(n, dtype=bool)
    errors: PointErrors = {}
    if out is None:
        out = {k: np.full(n, np.nan) for k in disc.outputs}
        for i in range(n):
            row = {k: v[i:i + 1] for k, v in batch.items()}
            if bad_in[i]:
                ok[i] = False
                errors[i] = PointError(f"{name}: non-finite input", describe_row(shown, i))
                continue
            try:
                one = _call(disc, row, 1)
            except ShapeError:
                raise
            except Exception as exc:  # the model's own error text is what the user needs
                ok[i] = False
                errors[i] = PointError(f"{name}: {type(exc).__name__}: {exc}", describe_row(shown, i))
                continue
            for k in disc.outputs:
                out[k][i] = one[k][0]
        finite = finite_rows([out[k] for k in disc.outputs], n)
    if not finite.all() or not ok.all():
        for i in np.flatnonzero(ok & ~finite):
            ok[i] = False
            bad = [k for k in disc.outputs if not np.isfinite(out[k][i])]
            errors[int(i)] = PointError(f"{name}: non-finite output {bad}", describe_row(shown, i))
        for k in disc.outputs:
            out[k] = np.where(ok, out[k], np.nan)
    res = EvalResult(out, ok, error_text(errors), time.perf_counter() - t0, point_errors=errors)
    return _with_partials(disc, batch, res, n, t0) if partials else res


def _with_partials(disc: Any, batch: Batch, res: EvalResult, n: int, t0: float) -> EvalResult:
    """Add the discipline's analytic partials (if it has any) at the evaluated points."""
    if not has_partials(disc) or n == 0:
        return res
    name = getattr(disc, "name", type(disc).__name__)
    good = np.asarray(res.ok, dtype=bool)
    rows = batch if good.all() else {k: v[good] for k, v in batch.items()}
    m = int(good.sum())
    if m == 0:
        part: dict = {}
    else:
        try:
            raw = disc.compute_partials(rows)
        except ShapeError:
            raise
        except Exception as exc:  # a bug of the discipline, not a bad point: one line naming it
            raise ShapeError(f"discipline {name!r}: compute_partials() raised {type(exc).__name__}: {exc}") from None
        if getattr(disc, "partials_flat", False):
            part = raw
        else:
            part = flat_partials(name, raw, {}, disc.outputs, disc.inputs, m)
    if m != n:
        part = {k: spread(col, good, n) for k, col in part.items()}
    bad = [] if m == n and all_finite(part.values()) else [
        k for k, c in part.items() if not np.isfinite(c[good]).all()]
    if bad:
        raise ShapeError(f"discipline {name!r}: partial d{bad[0][0]}/d{bad[0][1]} is not finite at an evaluated point")
    conv = getattr(disc, "unit_conversions", None)
    if conv:  # d out / d x in the run's unit = d out / d x in the declared unit x scale
        part = {k: (c * conv[k[1]][0] if k[1] in conv else c) for k, c in part.items()}
    res.extra["partials"] = part
    res.compute_time_s = time.perf_counter() - t0
    return res


def spread(col: np.ndarray, rows: np.ndarray, n: int) -> np.ndarray:
    """A column over n rows holding ``col`` at ``rows`` (indices or a mask) and NaN elsewhere."""
    full = np.full(n, np.nan)
    full[rows] = col
    return full


def _column(v: Any) -> np.ndarray:
    a = np.asarray(v, dtype=float)
    # compute() gets its own writable copy on every transport: a column decoded from a message
    # is a read-only view, and in process the caller's arrays must not change under it
    return (a if a.ndim == 1 else np.atleast_1d(a)).copy()


_isfinite, _and_all = np.isfinite, np.logical_and.reduce


def all_finite(columns) -> bool:
    """True when every value of every column is finite (columns of any shape)."""
    for c in columns:
        if not _and_all(_isfinite(c), axis=None):
            return False
    return True


def finite_rows(columns: list, n: int) -> np.ndarray:
    """Per row: every column finite."""
    if not columns:
        return np.ones(n, dtype=bool)
    good = np.isfinite(columns[0])
    for c in columns[1:]:
        good &= np.isfinite(c)
    return good


class DisciplineExit(RuntimeError):
    """A discipline's compute() called sys.exit(): a failure of that discipline, not the end of the run."""


def _call(disc: Any, batch: Batch, n: int) -> Batch:
    name = getattr(disc, "name", type(disc).__name__)
    try:
        raw = disc.compute(batch)
    except SystemExit as exc:  # a user model's sys.exit must not end the coordinator or a node silently
        raise DisciplineExit(f"compute() called sys.exit({exc.code!r})") from None
    out = check_outputs(name, raw, disc.outputs, {}, n, tuple(getattr(disc, "broadcast_outputs", ()) or ()))
    owned = all(b.base is None for b in batch.values())
    for k, v in out.items():
        # never hand back (a view of) an input array; two distinct arrays that each own their
        # memory cannot overlap, which settles the common case without may_share_memory
        if owned and v.base is None:
            if any(v is b for b in batch.values()):
                out[k] = v.copy()
        elif any(np.may_share_memory(v, b) for b in batch.values()):
            out[k] = v.copy()
    return out
