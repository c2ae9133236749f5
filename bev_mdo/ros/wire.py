"""Messages <-> batches of named arrays. The only place that knows the message layout.

A NamedArray is column-major: the values of ``names[j]`` for all points are
``values[j*batch_size:(j+1)*batch_size]``, so each column decodes without a copy.
"""
from __future__ import annotations

import array
from typing import Mapping

import numpy as np

from bev_mdo_msgs.msg import NamedArray

# Upper bounds that make a message "malformed" rather than merely large.
MAX_BATCH = 1_000_000
MAX_NAMES = 1024
MAX_NAME_LEN = 128


class WireError(ValueError):
    """A message does not hold a well-formed batch."""


def to_named_array(columns: Mapping[str, np.ndarray], msg: NamedArray | None = None) -> NamedArray:
    """Pack equal-length float columns into a NamedArray (one contiguous copy)."""
    msg = NamedArray() if msg is None else msg
    names = list(columns)
    cols = [np.ascontiguousarray(np.atleast_1d(columns[k]), dtype=np.float64) for k in names]
    n = cols[0].shape[0] if cols else 0
    if any(c.shape != (n,) for c in cols):
        raise WireError(f"columns have different lengths: { {k: c.shape for k, c in zip(names, cols)} }")
    msg.names = names
    msg.batch_size = n
    buf = array.array("d")
    if cols:
        buf.frombytes(np.concatenate(cols).tobytes())
    msg.values = buf
    return msg


def from_named_array(msg: NamedArray) -> dict[str, np.ndarray]:
    """Unpack a NamedArray; raise WireError when it is malformed."""
    names = list(msg.names)
    n = int(msg.batch_size)
    if n > MAX_BATCH:
        raise WireError(f"batch_size {n} exceeds {MAX_BATCH}")
    if len(names) > MAX_NAMES:
        raise WireError(f"{len(names)} names exceeds {MAX_NAMES}")
    if len(set(names)) != len(names):
        raise WireError("duplicate names")
    for k in names:
        if not k or len(k) > MAX_NAME_LEN or not k.isidentifier():
            raise WireError(f"bad variable name {k[:40]!r}")
    values = np.frombuffer(msg.values, dtype=np.float64) if len(msg.values) else np.zeros(0)
    if values.shape[0] != n * len(names):
        raise WireError(f"{values.shape[0]} values for {len(names)} names x batch {n}")
    return {k: values[j * n:(j + 1) * n] for j, k in enumerate(names)}


def bool_array(mask: np.ndarray) -> list[bool]:
    """A bool[] field value from a numpy mask."""
    return [bool(b) for b in np.asarray(mask, dtype=bool)]
