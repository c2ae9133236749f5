"""Batches of named float columns in and out of messages (NamedArray), and the evaluation messages
built from them.

A NamedArray is column-major: the values of ``names[j]`` for all points are
``values[j*batch_size:(j+1)*batch_size]``, so each column decodes without a copy.
"""
from __future__ import annotations

import array
import re
from collections import OrderedDict
from typing import Mapping

import numpy as np

from bev_mdo.mdo.discipline import PointError
from bev_mdo.mdo.vectors import is_variable_name, partial_name, split_partial_name
from bev_mdo.protocol.messages import (EvaluationRequest, EvaluationResult, NamedArray, WireError, decode, encode,
                                       new)

# Upper bounds that make a message "malformed" rather than merely large.
MAX_BATCH = 1_000_000
MAX_NAMES = 1024
MAX_NAME_LEN = 128
MAX_REASON_LEN = 1000  # characters of one point error's reason (and of its inputs) sent

_START_TAG = re.compile(r"start (\d+)/(\d+)(?: seed (-?\d+))?")  # start_tag's text
_F8 = np.dtype("<f8")
_GOOD_NAMES: set[tuple] = set()  # name lists that passed from_named_array's checks
_PARTIAL_KEYS: dict[tuple, list] = {}


def request(run_id: str = "", evaluation_id: int = 0, discipline: str = "", flow=(), iteration: int = 0):
    """A new EvaluationRequest (every other field at its default)."""
    return new(EvaluationRequest, run_id=run_id, evaluation_id=evaluation_id, discipline=discipline,
               flow=list(flow), iteration=iteration)


def result():
    """A new EvaluationResult, every field at its default."""
    return new(EvaluationResult)


def encode_request(msg) -> bytes:
    """CDR bytes of an EvaluationRequest (unsigned: signing.Signer.sign_request signs)."""
    return bytes(encode(msg))


encode_result = encode_request


def decode_request(data):
    """An EvaluationRequest from CDR bytes; WireError if they are not one."""
    return decode(data, EvaluationRequest)


def decode_result(data):
    """An EvaluationResult from CDR bytes; WireError if they are not one."""
    return decode(data, EvaluationResult)


# The last messages decoded in this process, by (decoder, bytes). Several nodes composed in one
# process (ros/composed.py) read the same sample (every source-less node reads the data-flow request):
# it is decoded once. Decoding is a pure function of the bytes and nothing changes a decoded message.
_DECODED: OrderedDict = OrderedDict()
_DECODED_MAX = 8


def decode_once(decode, data: bytes):
    """``decode(data)``, or the message decoded from the same bytes by the same decoder just before."""
    key = (decode, data)
    msg = _DECODED.get(key)
    if msg is None:
        msg = decode(data)  # WireError propagates: nothing is kept
        _DECODED[key] = msg
        if len(_DECODED) > _DECODED_MAX:
            _DECODED.popitem(last=False)
    return msg


def batch(columns: Mapping[str, np.ndarray]):
    """A NamedArray from equal-length float columns (concatenated column-major)."""
    names = list(columns)
    cols = []
    n = -1
    for k in names:
        c = columns[k]
        if type(c) is not np.ndarray or c.ndim != 1 or c.dtype != _F8:  # the usual column skips both
            c = np.atleast_1d(np.asarray(c, dtype=np.float64))
        if n < 0:
            n = c.shape[0]
        if c.shape != (n,):
            raise WireError(f"columns have different lengths: { {k: np.shape(columns[k]) for k in names} }")
        cols.append(c)
    return NamedArray(names, max(n, 0), np.concatenate(cols) if cols else np.zeros(0))


def to_named_array(columns: Mapping[str, np.ndarray], msg=None):
    """Pack equal-length float columns into a NamedArray (``msg``'s fields, or a new one)."""
    made = batch(columns)
    if msg is None:
        return made
    msg.names, msg.batch_size = made.names, made.batch_size
    # this module's messages hold numpy arrays; rclpy's generated classes want an array.array
    msg.values = made.values if hasattr(type(msg), "__msgtype__") else array.array("d", made.values.tobytes())
    return msg


def from_named_array(msg) -> dict[str, np.ndarray]:
    """Unpack a NamedArray; raise WireError when it is malformed."""
    names = list(msg.names)
    n = int(msg.batch_size)
    if n > MAX_BATCH:
        raise WireError(f"batch_size {n} exceeds {MAX_BATCH}")
    key = tuple(names)
    if key not in _GOOD_NAMES:  # the same few name lists come in every message of a run
        if len(names) > MAX_NAMES:
            raise WireError(f"{len(names)} names exceeds {MAX_NAMES}")
        if len(set(names)) != len(names):
            raise WireError("duplicate names")
        for k in names:
            if not k or len(k) > MAX_NAME_LEN or not is_variable_name(k):  # identifier, or a vector element x[3]
                raise WireError(f"bad variable name {k[:40]!r}")
        if len(_GOOD_NAMES) >= 4096:
            _GOOD_NAMES.clear()
        _GOOD_NAMES.add(key)
    values = msg.values if isinstance(msg.values, np.ndarray) else (
        np.frombuffer(msg.values, dtype=np.float64) if len(msg.values) else np.zeros(0))
    if values.shape[0] != n * len(names):
        raise WireError(f"{values.shape[0]} values for {len(names)} names x batch {n}")
    return {k: values[j * n:(j + 1) * n] for j, k in enumerate(names)}


def put_point_errors(m, point_errors: Mapping[int, PointError]) -> None:
    """Fill a result's ``error_points/_reasons/_inputs`` from {point index: PointError}."""
    m.error_points = np.array([int(i) for i in point_errors], dtype=np.uint32)
    m.error_reasons = [e.reason[:MAX_REASON_LEN] for e in point_errors.values()]
    m.error_inputs = [e.inputs[:MAX_REASON_LEN] for e in point_errors.values()]


def point_errors_of(m, n: int) -> dict[int, PointError]:
    """{point index: PointError} of a result of n points; WireError when the fields disagree."""
    if not len(m.error_points) and not len(m.error_reasons) and not len(m.error_inputs):
        return {}  # the common case: every point evaluated
    points, reasons, inputs = [int(i) for i in m.error_points], list(m.error_reasons), list(m.error_inputs)
    if not len(points) == len(reasons) == len(inputs):
        raise WireError(f"{len(points)} error points, {len(reasons)} reasons, {len(inputs)} inputs")
    if any(not 0 <= i < n for i in points) or len(set(points)) != len(points):
        raise WireError(f"error points outside the batch of {n} or repeated")
    return {i: PointError(r, x) for i, r, x in zip(points, reasons, inputs)}


def partials_batch(partials: Mapping[tuple[str, str], np.ndarray] | None, n: int):
    """The ``partials`` block of a result: asked for (batch n, a column per partial) or not (batch 0)."""
    if partials is None:
        return NamedArray([], 0, np.zeros(0))
    if not partials:
        return NamedArray([], n, np.zeros(0))
    return batch({partial_name(o, i): col for (o, i), col in partials.items()})


def partials_of(block, n: int) -> dict[tuple[str, str], np.ndarray] | None:
    """{(output, input): (n,)} from a result's ``partials`` block; None when it holds none.
    WireError when it is malformed."""
    if block is None or int(block.batch_size) != n or n == 0 or not len(block.names):
        return None
    names = list(block.names)
    values = np.asarray(block.values, dtype=float)
    if values.shape[0] != n * len(names) or len(set(names)) != len(names):
        raise WireError("malformed partials")
    key = tuple(names)
    keys = _PARTIAL_KEYS.get(key)
    if keys is None:  # the same few name lists come in every result of a run
        try:
            keys = [split_partial_name(k) for k in names]
        except ValueError as exc:
            raise WireError(str(exc)) from None
        if len(_PARTIAL_KEYS) >= 4096:
            _PARTIAL_KEYS.clear()
        _PARTIAL_KEYS[key] = keys
    return {k: values[j * n:(j + 1) * n] for j, k in enumerate(keys)}


def start_tag(start: int, starts: int, seed: int | None) -> str:
    """The header frame_id of a multi-start's IterationRecord (the .msg): which start made it, 1-based,
    and the seed of the sample (none for given start points)."""
    return f"start {start + 1}/{starts}" + ("" if seed is None else f" seed {seed}")


def parse_start_tag(tag: str) -> tuple[int, int, int | None] | None:
    """(start 0-based, starts, seed or None) of ``start_tag``'s text; None for any other text."""
    m = _START_TAG.fullmatch(tag)
    if m is None or not 1 <= int(m[1]) <= int(m[2]):
        return None
    return int(m[1]) - 1, int(m[2]), None if m[3] is None else int(m[3])


def fill_iteration_record(msg, rec: Mapping, run_id: str, sequence: int):
    """Fill an IterationRecord (header stamped by the caller) from a driver iteration record dict."""
    msg.run_id, msg.sequence, msg.iteration = run_id, int(sequence), int(rec["iteration"])
    msg.header.frame_id = start_tag(*rec["start"]) if rec.get("start") else ""  # a multi-start's: which start
    msg.formulation, msg.optimizer = str(rec.get("formulation", "")), str(rec.get("optimizer", ""))
    # the design variables, then (IDF) the couplings: the optimiser's variables, as the .msg says
    to_named_array({k: np.array([float(v)]) for k, v in {**rec["design"], **rec.get("couplings", {})}.items()},
                   msg.design)
    msg.objective_name, msg.objective = str(rec.get("objective_name", "")), float(rec["objective"])
    to_named_array({k: np.array([float(v)]) for k, v in rec.get("constraints", {}).items()}, msg.constraints)
    msg.max_violation = float(rec.get("max_violation", 0.0))
    msg.feasible = bool(rec.get("feasible", False))
    msg.mda_evaluations = int(rec.get("mda_evaluations", 0))
    counts = rec.get("discipline_evaluations", {})
    msg.discipline_names = list(counts)
    evaluations = [int(v) for v in counts.values()]
    msg.discipline_evaluations = (np.array(evaluations, dtype=np.uint64) if hasattr(type(msg), "__msgtype__")
                                  else evaluations)
    msg.wall_time_s = float(rec.get("wall_time_s", 0.0))
    return msg
