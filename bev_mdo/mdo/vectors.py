"""Vector variables, flattened to scalar columns named ``name[i]``.

A discipline declares vector inputs and outputs with a class (or instance) attribute
``shapes = {"x_shared": 6, "y_12": 2}`` (the number of elements of each vector; a name not
in ``shapes`` is a scalar). Its ``compute`` then gets a float64 array of shape (N, 6) for
``x_shared`` (N points), and returns (N, size) for every vector output, (N,) for scalars.

Everywhere else -- the coupling graph, the MDA, the formulations, the ROS messages, the bags,
history and CSV -- a vector is its elements, one scalar column each, named ``x_shared[0]`` ..
``x_shared[5]``. ``VectorDiscipline`` wraps such a discipline so that its ``inputs`` and
``outputs`` are the element names and ``compute`` packs and unpacks; ``config.resolve_disciplines``
wraps every discipline that declares ``shapes``, the same way for both transports.

Partial derivatives (``compute_partials``, see docs/derivatives.md) are returned per pair of
(base) names as arrays (N, out_size, in_size); :func:`flat_partials` checks their shapes and
turns them into one (N,) column per pair of element names.
"""
from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

VAR_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\[\d+\])?$")
_ELEMENT = re.compile(r"^(.*)\[(\d+)\]$")
PARTIAL_SEP = "/"  # a partial column is named "output/input" (element names), e.g. "y_1/x_shared[3]"


class ShapeError(ValueError):
    """A discipline returned an output or a partial of the wrong shape (a wiring mistake, not a bad point)."""


CONTRACT = "bad_discipline_output"  # the kind of a node's rejection for a discipline's own mistake (a ShapeError)


def rejection(name: str, why: str, kind: str = "") -> str:
    """The error of a request discipline `name` refused (every transport's): one of the ``CONTRACT`` kind is
    marked, so the coordinator reads it back (``broken_contract``) and stops the run as in process."""
    return f"{name}: rejected{' (broke its contract)' * (kind == CONTRACT)}: {why}"


def broken_contract(name: str, error: str) -> str | None:
    """The discipline's own one line (the ShapeError in-process runs stop with) of a ``rejection`` of the
    ``CONTRACT`` kind by `name`; None for any other error."""
    head = rejection(name, "", CONTRACT)
    return error[len(head):] if error.startswith(head) else None


def flat_names(name: str, size: int | None) -> list[str]:
    """The scalar columns of a variable: [name] for a scalar, name[0]..name[size-1] for a vector."""
    return [name] if size is None else [f"{name}[{i}]" for i in range(int(size))]


def base_name(flat: str) -> str:
    """``x_shared`` for ``x_shared[3]``; the name itself for a scalar."""
    m = _ELEMENT.match(flat)
    return m.group(1) if m else flat


def did_you_mean(name: str, names, cutoff: float = 0.6) -> str:
    """``did you mean 'range_km'? `` (the nearest of ``names`` by difflib), or "": the one hint of every
    unknown name a user gives (a design, a fixed value, an objective, --at, --wrt)."""
    from bev_mdo.models.common import name_hint

    return name_hint(name, names, cutoff)


def is_variable_name(name: str) -> bool:
    """A scalar name (identifier) or a vector element name (identifier[i])."""
    return bool(VAR_RE.match(name))


def partial_name(out: str, inp: str) -> str:
    return f"{out}{PARTIAL_SEP}{inp}"


def split_partial_name(name: str) -> tuple[str, str]:
    """(output, input) of a partial column name; ValueError if it is not one."""
    out, sep, inp = name.partition(PARTIAL_SEP)
    if not sep or not is_variable_name(out) or not is_variable_name(inp):
        raise ValueError(f"bad partial name {name[:60]!r}")
    return out, inp


def shapes_of(disc: Any) -> dict[str, int]:
    """The declared vector sizes of a discipline (empty for an all-scalar one); ValueError names it."""
    raw = getattr(disc, "shapes", None) or {}
    name = getattr(disc, "name", type(disc).__name__)
    if not isinstance(raw, Mapping):
        raise ValueError(f"discipline {name!r}: shapes must map variable names to sizes")
    out = {}
    for k, v in raw.items():
        if isinstance(v, (tuple, list)) and len(v) == 1:
            v = v[0]
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise ValueError(f"discipline {name!r}: shapes[{k!r}] = {v!r} must be a positive integer")
        out[str(k)] = int(v)
    return out


def check_declaration(disc: Any) -> None:
    """A discipline names each input and output once, and no output is also an input."""
    name = getattr(disc, "name", type(disc).__name__)
    for kind in ("inputs", "outputs"):
        names = list(getattr(disc, kind))
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"discipline {name!r} names {kind[:-1]} {dup[0]!r} twice in its {kind}")


def has_partials(disc: Any) -> bool:
    """True if the discipline provides analytic partial derivatives."""
    return callable(getattr(disc, "compute_partials", None)) and bool(getattr(disc, "provides_partials", True))


_any_nonzero = np.logical_or.reduce  # NaN counts as nonzero, as in ``col != 0.0``


def flat_partials(disc_name: str, raw: Any, sizes: Mapping[str, int], outputs: Sequence[str],
                  inputs: Sequence[str], n: int) -> dict[tuple[str, str], np.ndarray]:
    """Check ``compute_partials``' result and flatten it to {(output element, input element): (n,)}.

    ``raw`` maps (output, input) base names to arrays (n, out_size, in_size); for a scalar output
    and a scalar input (n,) is accepted too. Pairs not given are zero. Columns that are zero for
    every point are left out (they are zero by the same rule). Raises ShapeError naming the
    discipline for anything else."""
    if not isinstance(raw, Mapping):
        raise ShapeError(f"discipline {disc_name!r}: compute_partials() must return a dict "
                         "{(output, input): array (N, out_size, in_size)}, got " + type(raw).__name__)
    outs, ins = set(outputs), set(inputs)
    flat: dict[tuple[str, str], np.ndarray] = {}
    first = None
    for key, value in raw.items():
        if not (isinstance(key, tuple) and len(key) == 2):
            raise ShapeError(f"discipline {disc_name!r}: compute_partials() key {key!r} must be (output, input)")
        o, i = key
        if o not in outs:
            raise ShapeError(f"discipline {disc_name!r}: compute_partials() gives d{o}/d{i}, but {o!r} is not one "
                             f"of its outputs {list(outputs)}")
        if i not in ins:
            raise ShapeError(f"discipline {disc_name!r}: compute_partials() gives d{o}/d{i}, but {i!r} is not one "
                             f"of its inputs {list(inputs)}")
        so, si = sizes.get(o), sizes.get(i)
        a = np.asarray(value, dtype=float)
        if so is None and si is None and (a.shape == (n,) or a.shape == (n, 1, 1)):
            # scalar by scalar (the common case): the same rule as below, without the element loops
            col = a if a.ndim == 1 else a[:, 0, 0]
            if _any_nonzero(col, axis=None):
                flat[(o, i)] = np.array(col)
            elif not flat and first is None:
                first = ((o, i), np.array(col))
            continue
        want = (n, so or 1, si or 1)
        if a.shape == (n,) and so is None and si is None:
            a = a.reshape(want)
        if a.shape != want:
            raise ShapeError(f"discipline {disc_name!r}: partial d{o}/d{i} has shape {a.shape}, expected {want} "
                             "(points, output size, input size)")
        for p, fo in enumerate(flat_names(o, so)):
            for q, fi in enumerate(flat_names(i, si)):
                col = a[:, p, q]
                if np.any(col != 0.0):
                    flat[(fo, fi)] = np.array(col)
                elif not flat and first is None:
                    first = ((fo, fi), np.array(col))
    if not flat and first is not None:  # all zero: keep one column, so "has partials" survives the wire
        flat[first[0]] = first[1]
    return flat


def check_outputs(disc_name: str, raw: Any, outputs: Sequence[str], sizes: Mapping[str, int], n: int,
                  broadcast: Sequence[str] = ()) -> dict[str, np.ndarray]:
    """compute()'s result as {output: (n,) or (n, size)}; ShapeError names the discipline and the output.

    One value for a whole batch of n > 1 points is an error unless the discipline lists that
    output in ``broadcast_outputs`` (a constant on purpose)."""
    if not isinstance(raw, Mapping):
        raise ShapeError(f"discipline {disc_name!r}: compute() must return a dict of outputs, got {type(raw).__name__}")
    out = {}
    for k in outputs:
        if k not in raw:
            raise ShapeError(f"discipline {disc_name!r}: compute() did not return output {k!r}")
        if np.iscomplexobj(raw[k]):  # float() would drop the imaginary part, with only a ComplexWarning
            raise ValueError(f"output {k!r} is complex, e.g. {np.ravel(raw[k])[0]}: return real numbers")
        # a masked value has no value: NaN, the point fails (np.asarray took the data under the mask as a value)
        v = np.ma.filled(np.ma.asarray(raw[k], dtype=float), np.nan) if np.ma.isMaskedArray(raw[k]) else np.asarray(raw[k])
        if v.dtype.kind in "USO":  # float() reads '3.5' as 3.5: text is a discipline's bug, never a value
            text = next((x for x in v.flat if isinstance(x, (str, bytes, np.str_, np.bytes_))), None)
            if text is not None:
                raise ShapeError(f"discipline {disc_name!r}: output {k!r} is text ({str(text)!r}), not a number: "
                                 "return numbers")
        v = np.asarray(v, dtype=float)
        size = sizes.get(k)
        want = (n,) if size is None else (n, size)
        if v.shape != want:
            if k in broadcast:
                try:
                    v = np.broadcast_to(v, want).copy()
                except ValueError:
                    pass
            if v.shape != want:
                if size is None and v.shape == (n, 1):
                    v = v[:, 0]
                else:
                    raise ShapeError(f"discipline {disc_name!r}: output {k!r} has shape {v.shape}, expected {want} "
                                     "(one value per point" + (" and element" if size else "") + "; list it in "
                                     "broadcast_outputs to broadcast a constant on purpose)")
        out[k] = v
    return out


class VectorDiscipline:
    """A discipline with vector variables, seen as scalar columns ``name[i]`` (see the module doc)."""

    def __init__(self, inner: Any):
        self.inner = inner
        self.sizes = shapes_of(inner)
        check_declaration(inner)
        self.base_inputs = tuple(inner.inputs)
        self.base_outputs = tuple(inner.outputs)
        unknown = [k for k in self.sizes if k not in self.base_inputs and k not in self.base_outputs]
        if unknown:
            raise ValueError(f"discipline {self.name!r}: shapes names {unknown}, which are neither inputs nor outputs")
        self.inputs = tuple(f for k in self.base_inputs for f in flat_names(k, self.sizes.get(k)))
        self.outputs = tuple(f for k in self.base_outputs for f in flat_names(k, self.sizes.get(k)))
        self.parameters = dict(getattr(inner, "parameters", {}) or {})
        self.provides_partials = has_partials(inner)

    @property
    def name(self) -> str:
        return getattr(self.inner, "name", "") or type(self.inner).__name__

    @name.setter
    def name(self, value: str) -> None:
        self.inner.name = value

    def __getattr__(self, attr: str):  # options and anything else of the wrapped discipline
        if attr == "inner":
            raise AttributeError(attr)
        return getattr(self.inner, attr)

    def _pack(self, inputs: Mapping[str, np.ndarray]) -> tuple[dict[str, np.ndarray], int]:
        """(the inner discipline's batch, with its vectors as (N, size) arrays; N)."""
        out = {}
        for k in self.base_inputs:
            size = self.sizes.get(k)
            out[k] = inputs[k] if size is None else np.column_stack([inputs[f] for f in flat_names(k, size)])
        for p in self.parameters:
            if p in inputs:
                out[p] = inputs[p]
        return out, len(next(iter(inputs.values()))) if inputs else 0

    def compute(self, inputs: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        batch, n = self._pack(inputs)
        raw = check_outputs(self.name, self.inner.compute(batch), self.base_outputs, self.sizes, n,
                            tuple(getattr(self.inner, "broadcast_outputs", ()) or ()))
        out = {}
        for k, v in raw.items():
            size = self.sizes.get(k)
            if size is None:
                out[k] = v
            else:
                for i, f in enumerate(flat_names(k, size)):
                    out[f] = v[:, i]
        return out

    def compute_partials(self, inputs: Mapping[str, np.ndarray]) -> dict[tuple[str, str], np.ndarray]:
        """Flat partials {(output element, input element): (N,)} (already checked)."""
        batch, n = self._pack(inputs)
        return flat_partials(self.name, self.inner.compute_partials(batch), self.sizes, self.base_outputs,
                             self.base_inputs, n)

    partials_flat = True  # compute_partials already returns checked element columns


def wrap(disc: Any) -> Any:
    """The discipline as the engine sees it: wrapped if it declares vector shapes, else itself."""
    check_declaration(disc)
    if shapes_of(disc):
        return VectorDiscipline(disc)
    return disc


def expand(value: Any, size: int, where: str) -> list:
    """A per-element list from a scalar (broadcast) or a list of ``size`` values."""
    if isinstance(value, (list, tuple)):
        if len(value) != size:
            raise ValueError(f"{where}: has {len(value)} values, expected {size} (shape) or one scalar")
        return list(value)
    return [value] * size
