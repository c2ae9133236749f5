"""Messages <-> batches of named arrays. The only place that knows the message layout.

A NamedArray is column-major: the values of ``names[j]`` for all points are
``values[j*batch_size:(j+1)*batch_size]``, so each column decodes without a copy.
"""
from __future__ import annotations

import array
from typing import Callable, Mapping

import numpy as np

from bev_mdo.mdo.discipline import PointError
from bev_mdo.mdo.vectors import is_variable_name, partial_name, split_partial_name
from bev_mdo_msgs.msg import NamedArray

# Upper bounds that make a message "malformed" rather than merely large.
MAX_BATCH = 1_000_000
MAX_NAMES = 1024
MAX_NAME_LEN = 128


_F8 = np.dtype("<f8")
_GOOD_NAMES: set[tuple] = set()  # name lists that passed from_named_array's checks


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
    if type(msg) is Batch:
        columns = msg.checked_columns()
        if columns is not None:  # made in this process by batch() and not changed since: nothing to decode
            return columns
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




# ---------------------------------------------------------------------------------------------
# Lean CDR codec for the two hot-path messages (EvaluationRequest, EvaluationResult).
#
# rclpy turns every received message into Python message objects whose generated setters check
# each field, and its executor rebuilds a wait set per spin: measured here a request/reply over
# typed messages and an executor costs ~290 us and ~410 us of CPU per side, the same exchange of
# raw CDR bytes ~90 us and ~56 us. Nodes and coordinator therefore take and publish raw bytes
# (``raw=True`` subscriptions, ``Publisher.publish(bytes)``) and use this codec: plain CDR
# (XCDR1, little endian, the encapsulation rmw_fastrtps uses for ROS 2 messages), checked
# against rclpy's own serialisation in test/ros/test_wire.py. The decoded objects have the
# message's field names, so code that reads a message (auth.py) reads them too.
# ---------------------------------------------------------------------------------------------
import struct

_ENCAPSULATION = b"\x00\x01\x00\x00"  # CDR_LE
_U32 = struct.Struct("<I")
_STAMP = struct.Struct("<iI")
_U64X2 = struct.Struct("<QQ")
_U32X2 = struct.Struct("<II")
_F64 = struct.Struct("<d")
_U32X3 = struct.Struct("<III")


class Stamp:
    __slots__ = ("sec", "nanosec")

    def __init__(self, sec: int = 0, nanosec: int = 0):
        self.sec, self.nanosec = sec, nanosec


class Header:
    __slots__ = ("stamp", "frame_id")

    def __init__(self, stamp: Stamp | None = None, frame_id: str = ""):
        self.stamp, self.frame_id = stamp or Stamp(), frame_id


class Batch:
    """A NamedArray as decoded by the codec: ``values`` is a float64 numpy array.

    A batch made in this process (``batch``) also keeps its ``columns`` (float64 arrays, one per
    name) and makes ``values`` (their column-major concatenation) only when something reads
    it, which only the encoder does: a message handed to a node or to the coordinator in the same
    process (composed.Beside, link_local) is read by ``from_named_array`` without a concatenation or a
    slice, and one that is published is encoded to the same bytes as before."""

    __slots__ = ("names", "batch_size", "_values", "columns", "_made")

    def __init__(self, names=(), batch_size: int = 0, values=None, columns=None):
        self.names = list(names)
        self.batch_size = batch_size
        self._values = _NO_VALUES if values is None and columns is None else values
        self.columns = columns
        self._made = (self.names, batch_size)  # what batch() checked (from_named_array: unchanged since?)

    @property
    def values(self):
        if self._values is None:
            cols = self.columns
            self._values = np.concatenate(list(cols.values())) if cols else np.zeros(0)
        return self._values

    @values.setter
    def values(self, v) -> None:
        self._values, self.columns = v, None

    def checked_columns(self) -> dict | None:
        """The columns a batch() was made of, if its names and size were not changed since (None:
        a decoded batch, or one changed by hand, which from_named_array checks as received)."""
        cols = self.columns
        if cols is None or self.names is not self._made[0] or self.batch_size != self._made[1]:
            return None
        return dict(cols)


# Empty arrays every new message starts with (read-only: shared, and replaced, never written)
_NO_VALUES = np.zeros(0)
_NO_VALUES.flags.writeable = False
_NO_POINTS = np.zeros(0, dtype=bool)
_NO_POINTS.flags.writeable = False


class Request:
    """bev_mdo_msgs/EvaluationRequest, field for field."""

    __slots__ = ("header", "run_id", "evaluation_id", "sequence", "iteration", "attempt", "discipline", "inputs",
                 "flow", "signature", "partials", "raw", "sig_at", "end")

    def __init__(self, run_id: str = "", evaluation_id: int = 0, discipline: str = "", flow=(), iteration: int = 0):
        self.header = Header()
        self.run_id, self.evaluation_id, self.sequence = run_id, evaluation_id, 0
        self.iteration, self.attempt, self.discipline = iteration, 0, discipline
        self.inputs = Batch()
        self.flow = list(flow)
        self.signature = ""
        self.partials = False
        self.raw, self.sig_at, self.end = None, 0, 0  # set by decode_request: see signed_bytes


class Result:
    """bev_mdo_msgs/EvaluationResult, field for field (``point_ok`` a bool numpy array)."""

    __slots__ = ("header", "run_id", "evaluation_id", "sequence", "discipline", "instance", "status", "error",
                 "point_ok", "outputs", "compute_time_s", "flow", "signature", "partials",
                 "error_points", "error_reasons", "error_inputs", "raw", "sig_at", "end")

    def __init__(self):
        self.header = Header()
        self.run_id, self.evaluation_id, self.sequence = "", 0, 0
        self.discipline, self.instance, self.status, self.error = "", "", 0, ""
        self.point_ok = _NO_POINTS
        self.outputs = Batch()
        self.compute_time_s = 0.0
        self.flow: list[str] = []
        self.signature = ""
        self.partials = Batch()
        self.error_points: list[int] = []
        self.error_reasons: list[str] = []
        self.error_inputs: list[str] = []
        self.raw, self.sig_at, self.end = None, 0, 0  # set by decode_result: see signed_bytes


MAX_REASON_LEN = 1000  # characters of one point error's reason (and of its inputs) sent


def put_point_errors(m, point_errors: Mapping[int, PointError]) -> None:
    """Fill a result's ``error_points/_reasons/_inputs`` from {point index: PointError}."""
    m.error_points = [int(i) for i in point_errors]
    m.error_reasons = [e.reason[:MAX_REASON_LEN] for e in point_errors.values()]
    m.error_inputs = [e.inputs[:MAX_REASON_LEN] for e in point_errors.values()]


def point_errors_of(m, n: int) -> dict[int, PointError]:
    """{point index: PointError} of a result of n points; WireError when the fields disagree."""
    if not len(m.error_points) and not len(m.error_reasons) and not len(m.error_inputs):
        return {}  # the common case: every point evaluated
    points, reasons, inputs = list(m.error_points), list(m.error_reasons), list(m.error_inputs)
    if not len(points) == len(reasons) == len(inputs):
        raise WireError(f"{len(points)} error points, {len(reasons)} reasons, {len(inputs)} inputs")
    if any(not 0 <= int(i) < n for i in points) or len(set(points)) != len(points):
        raise WireError(f"error points outside the batch of {n} or repeated")
    return {int(i): PointError(r, x) for i, r, x in zip(points, reasons, inputs)}


def partials_batch(partials: Mapping[tuple[str, str], np.ndarray] | None, n: int) -> Batch:
    """The ``partials`` block of a result: asked for (batch n, a column per partial) or not (batch 0)."""
    if partials is None:
        return Batch()
    if not partials:
        return Batch((), n, np.zeros(0))
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


_PARTIAL_KEYS: dict[tuple, list] = {}


def batch(columns: Mapping[str, np.ndarray]) -> Batch:
    """A Batch from equal-length columns (float64, kept as they are: a reader in this process gets
    the caller's arrays, as the in-process evaluator passes them), concatenated column-major only
    if the batch is encoded (Batch.values)."""
    names = list(columns)
    cols = {}
    n = -1
    for k in names:
        c = columns[k]
        if type(c) is not np.ndarray or c.ndim != 1 or c.dtype != _F8:  # the usual column skips both
            c = np.atleast_1d(np.asarray(c, dtype=np.float64))
        if n < 0:
            n = c.shape[0]
        if c.shape != (n,):
            raise WireError(f"columns have different lengths: { {k: np.shape(columns[k]) for k in names} }")
        cols[k] = c
    return Batch(names, max(n, 0), None, cols)


# Encoding. Short strings (names, ids, the flow list) repeat in every message of a run, so their
# CDR bytes are cached; everything is appended to a list of parts and joined once. ``n`` counts
# payload bytes (after the 4-byte encapsulation header), which is what CDR aligns to.
_PAD = tuple(b"\x00" * k for k in range(8))
_TEXT: dict[str, bytes] = {}
_TEXTS: dict[tuple, bytes] = {}
_CACHE_MAX = 4096


def _cdr_text(s: str) -> bytes:
    """A CDR string: u32 length (NUL included), UTF-8, NUL; the caller aligns it to 4."""
    b = _TEXT.get(s)
    if b is None:
        e = s.encode("utf-8")
        b = _U32.pack(len(e) + 1) + e + b"\x00"
        if len(e) <= 128 and len(_TEXT) < _CACHE_MAX:
            _TEXT[s] = b
    return b


def _cdr_texts(items) -> bytes:
    """A CDR sequence of strings, laid out from a 4-aligned offset (as it always starts)."""
    key = tuple(items)
    b = _TEXTS.get(key)
    if b is None:
        out = bytearray(_U32.pack(len(key)))
        for s in key:
            out += _PAD[-len(out) % 4]
            out += _cdr_text(s)
        b = bytes(out)
        if len(b) <= 2048 and len(_TEXTS) < _CACHE_MAX:
            _TEXTS[key] = b
    return b


def _named_bytes(out: bytearray, a) -> None:
    """A NamedArray appended to ``out`` (payload offsets = len(out) - 4, past the encapsulation)."""
    out += _PAD[-(len(out) - 4) % 4]
    out += _cdr_texts(a.names)
    values = a.values
    if type(values) is not np.ndarray or values.dtype != _F8 or not values.flags.c_contiguous:
        values = np.ascontiguousarray(values, dtype="<f8")
    out += _PAD[-(len(out) - 4) % 4]
    out += _U32X2.pack(int(a.batch_size), values.size)
    if values.size:
        out += _PAD[-(len(out) - 4) % 8]
        out += values.tobytes()



def _text_at(out: bytearray, s: str) -> int:
    """A string appended to ``out`` at the next 4-aligned payload offset; returns where it starts."""
    out += _PAD[-(len(out) - 4) % 4]
    at = len(out)
    out += _cdr_text(s)
    return at


# Signing covers the bytes that are sent. The signature is a string field (hex HMAC-SHA256, 64
# characters): the message is encoded once with that field empty (``BLANK_SIGNATURE``, 5 bytes), the
# MAC is taken over exactly those bytes, and the 69 bytes of the signed field replace the 5 blank
# ones. 64 bytes more keep every later field's CDR alignment (4 or 8), so nothing else moves. A
# receiver blanks the field in the bytes it received and MACs them (``signed_bytes``).
SIGNATURE_CHARS = 64
BLANK_SIGNATURE = _U32.pack(1) + b"\x00"
_SIGNED_LEN = _U32.pack(SIGNATURE_CHARS + 1)


def signed(out: bytearray, at: int, m, mac: Callable[[bytearray], str]) -> bytes:
    """Sign ``out``, CDR bytes with a blank signature field at ``at``: MAC them, put the signature
    in its field (and in ``m.signature``); returns the bytes to send."""
    sig = mac(out)
    field = _SIGNED_LEN + sig.encode("ascii") + b"\x00"
    if len(field) != len(BLANK_SIGNATURE) + SIGNATURE_CHARS or out[at:at + len(BLANK_SIGNATURE)] != BLANK_SIGNATURE:
        raise ValueError("a signature is 64 ASCII characters, put in a blank signature field")
    out[at:at + len(BLANK_SIGNATURE)] = field
    m.signature = sig
    return bytes(out)


def signed_bytes(data, at: int, end: int) -> tuple | None:
    """The parts of received CDR bytes ``data[:end]`` that a signature at offset ``at`` covers: the
    bytes with that field blanked, as (before, BLANK_SIGNATURE, after) memoryviews (no copy). ``end``
    is where the message ends: DDS may pad what it delivers to a multiple of 4 bytes, and the
    sender signed the message without that padding. None when the field does not hold a signature
    of 64 ASCII characters (it cannot verify)."""
    mv = memoryview(data)
    stop = at + len(BLANK_SIGNATURE) + SIGNATURE_CHARS
    if mv[at:at + 4] != _SIGNED_LEN or stop > end or mv[stop - 1] != 0:
        return None
    return mv[:at], BLANK_SIGNATURE, mv[stop:end]


def unsigned_request(m) -> bytearray:
    """The bytes a signature of EvaluationRequest ``m`` covers: its CDR with the signature blank."""
    return _request_cdr(m, "")[0]


def unsigned_result(m) -> bytearray:
    """The bytes a signature of EvaluationResult ``m`` covers: its CDR with the signature blank."""
    return _result_cdr(m, "")[0]


def _head(m) -> bytearray:
    """The start both evaluation messages share: encapsulation, header and run id, padded for the
    uint64 ids that follow. One bytearray, aligned by its length (the payload starts after the
    4-byte encapsulation)."""
    out = bytearray(_ENCAPSULATION)
    out += _STAMP.pack(int(m.header.stamp.sec), int(m.header.stamp.nanosec))
    out += _cdr_text(m.header.frame_id)
    _text_at(out, m.run_id)
    out += _PAD[-(len(out) - 4) % 8]
    return out


def encode_request(m, mac: Callable[[bytearray], str] | None = None) -> bytes:
    """CDR bytes of an EvaluationRequest (a Request or a generated message); signed with ``mac``
    when given (see ``signed``)."""
    out, at = _request_cdr(m, "" if mac else m.signature)
    return signed(out, at, m, mac) if mac else bytes(out)


def _request_cdr(m, signature: str) -> tuple[bytearray, int]:
    """(CDR bytes of an EvaluationRequest with ``signature``, where the signature field starts)."""
    out = _head(m)
    out += _U64X2.pack(int(m.evaluation_id), int(m.sequence)) + _U32X2.pack(int(m.iteration), int(m.attempt))
    _text_at(out, m.discipline)
    _named_bytes(out, m.inputs)
    out += _PAD[-(len(out) - 4) % 4]
    out += _cdr_texts(m.flow)
    at = _text_at(out, signature)
    out += b"\x01" if m.partials else b"\x00"
    return out, at


def encode_result(m, mac: Callable[[bytearray], str] | None = None) -> bytes:
    """CDR bytes of an EvaluationResult (a Result or a generated message); signed with ``mac``
    when given (see ``signed``)."""
    out, at = _result_cdr(m, "" if mac else m.signature)
    return signed(out, at, m, mac) if mac else bytes(out)


def _result_cdr(m, signature: str) -> tuple[bytearray, int]:
    """(CDR bytes of an EvaluationResult with ``signature``, where the signature field starts)."""
    out = _head(m)
    out += _U64X2.pack(int(m.evaluation_id), int(m.sequence))
    _text_at(out, m.discipline)
    _text_at(out, m.instance)
    out.append(int(m.status))
    _text_at(out, m.error)
    ok = m.point_ok
    if type(ok) is not np.ndarray or ok.dtype != np.bool_:
        ok = np.asarray(ok, dtype=bool)
    out += _PAD[-(len(out) - 4) % 4]
    out += _U32.pack(ok.size)
    out += ok.tobytes()  # numpy bools are one byte, 0 or 1, as CDR's
    _named_bytes(out, m.outputs)
    out += _PAD[-(len(out) - 4) % 8]
    out += _F64.pack(float(m.compute_time_s))
    out += _cdr_texts(m.flow)  # 8-aligned here, so 4-aligned
    at = _text_at(out, signature)
    _named_bytes(out, m.partials)
    _put_errors(out, m)
    return out, at


def _plain_texts(items) -> bytes:
    """A CDR sequence of strings from a 4-aligned offset, not cached (error texts vary)."""
    out = bytearray(_U32.pack(len(items)))
    for s in items:
        out += _PAD[-len(out) % 4]
        e = s.encode("utf-8")
        out += _U32.pack(len(e) + 1) + e + b"\x00"
    return bytes(out)


_NO_ERRORS = bytes(12)  # three empty sequences (error_points, error_reasons, error_inputs)


def _put_errors(out: bytearray, m) -> None:
    """The point-error fields (error_points, error_reasons, error_inputs) of a result, each 4-aligned."""
    out += _PAD[-(len(out) - 4) % 4]
    points = m.error_points
    if not len(points):  # the common case: every point evaluated
        out += _NO_ERRORS
        return
    out += _U32.pack(len(points))
    out += np.asarray(points, dtype="<u4").tobytes()
    out += _plain_texts(list(m.error_reasons))
    out += _PAD[-(len(out) - 4) % 4]
    out += _plain_texts(list(m.error_inputs))


# Decoding. ``data`` is a memoryview of the payload (offsets count from after the encapsulation
# header, as CDR aligns). Sequences of strings that repeat (names, the flow list) are looked up by
# their raw bytes instead of being decoded again.
_SEEN: dict[bytes, list[str]] = {}


def _string(data, pos: int) -> tuple[str, int]:
    """A CDR string at ``pos`` (aligned to 4 here); returns (text, next pos)."""
    pos += -pos % 4
    (n,) = _U32.unpack_from(data, pos)
    end = pos + 4 + n
    if end > len(data) or (n and data[end - 1] != 0):
        raise WireError("message truncated" if end > len(data) else "string without its NUL")
    return (str(data[pos + 4:end - 1], "utf-8") if n else ""), end


def _strings(data, pos: int, limit: int) -> tuple[list[str], int]:
    pos += -pos % 4
    (count,) = _U32.unpack_from(data, pos)
    if count > limit or count * 4 > len(data) - pos - 4:
        raise WireError(f"sequence of {count} strings")
    start, end = pos, pos + 4
    for _ in range(count):  # find the end first: a sequence seen before is not decoded again
        end += -end % 4
        (n,) = _U32.unpack_from(data, end)
        end += 4 + n
    if end > len(data):
        raise WireError("message truncated")
    key = bytes(data[start:end])
    got = _SEEN.get(key)
    if got is None:
        got, p = [], start + 4
        for _ in range(count):
            text, p = _string(data, p)
            got.append(text)
        if len(key) <= 2048 and len(_SEEN) < _CACHE_MAX:
            _SEEN[key] = got
    return list(got), end


def _header(data, pos: int) -> tuple[Header, int]:
    sec, nsec = _STAMP.unpack_from(data, pos)
    frame, pos = _string(data, pos + 8)
    return Header(Stamp(sec, nsec), frame), pos


def _ids(m, data) -> int:
    """The fields both messages start with (header, run_id, evaluation_id, sequence) into ``m``;
    returns the position after them."""
    m.header, pos = _header(data, 0)
    m.run_id, pos = _string(data, pos)
    pos += -pos % 8
    m.evaluation_id, m.sequence = _U64X2.unpack_from(data, pos)
    return pos + 16


def _named(data, pos: int) -> tuple[Batch, int]:
    names, pos = _strings(data, pos, MAX_NAMES * 4)
    pos += -pos % 4
    n, count = _U32X2.unpack_from(data, pos)
    pos += 8
    if count:
        pos += -pos % 8
    if pos + 8 * count > len(data):
        raise WireError("message truncated")
    values = np.frombuffer(data, dtype="<f8", count=count, offset=pos)
    return Batch(names, n, values), pos + 8 * count


def _decoding(fn):
    """Decode CDR bytes with ``fn(data)``; any malformation becomes WireError."""
    def decode(data: bytes):
        if len(data) < 4 or data[:2] != b"\x00\x01":
            raise WireError("not little-endian CDR")
        try:
            m = fn(memoryview(data)[4:])  # offsets count from the payload, as CDR aligns
            m.raw = data  # what a signature covers (signed_bytes)
            return m
        except WireError:
            raise
        except (struct.error, UnicodeDecodeError, ValueError, IndexError) as exc:
            raise WireError(f"malformed message ({exc})") from None
    decode.__doc__ = fn.__doc__
    return decode


@_decoding
def decode_request(data) -> Request:
    """A Request from CDR bytes; WireError if they are not one."""
    m = Request.__new__(Request)
    pos = _ids(m, data)
    m.iteration, m.attempt = _U32X2.unpack_from(data, pos)
    m.discipline, pos = _string(data, pos + 8)
    m.inputs, pos = _named(data, pos)
    m.flow, pos = _strings(data, pos, MAX_NAMES)
    m.sig_at = pos + -pos % 4 + 4  # in the received bytes, past the encapsulation
    m.signature, pos = _string(data, pos)
    m.partials = data[pos] != 0
    m.end = pos + 1 + 4
    return m


@_decoding
def decode_result(data) -> Result:
    """A Result from CDR bytes; WireError if they are not one."""
    m = Result.__new__(Result)
    m.discipline, pos = _string(data, _ids(m, data))
    m.instance, pos = _string(data, pos)
    m.status = data[pos]
    m.error, pos = _string(data, pos + 1)
    pos += -pos % 4
    (n,) = _U32.unpack_from(data, pos)
    pos += 4
    if pos + n > len(data):
        raise WireError("message truncated")
    m.point_ok = np.frombuffer(data, dtype=np.uint8, count=n, offset=pos) != 0
    m.outputs, pos = _named(data, pos + n)
    pos += -pos % 8
    (m.compute_time_s,) = _F64.unpack_from(data, pos)
    m.flow, pos = _strings(data, pos + 8, MAX_NAMES)
    m.sig_at = pos + -pos % 4 + 4  # in the received bytes, past the encapsulation
    m.signature, pos = _string(data, pos)
    m.partials, pos = _named(data, pos)
    pos += -pos % 4
    if len(data) - pos == 12 and _U32X3.unpack_from(data, pos) == (0, 0, 0):  # the common case: no point error
        m.error_points, m.error_reasons, m.error_inputs = [], [], []
        m.end = pos + 12 + 4
        return m
    (count,) = _U32.unpack_from(data, pos)
    pos += 4
    if count > MAX_BATCH or pos + 4 * count > len(data):
        raise WireError(f"{count} error points")
    m.error_points = np.frombuffer(data, dtype="<u4", count=count, offset=pos).tolist()
    m.error_reasons, pos = _plain_strings(data, pos + 4 * count)
    m.error_inputs, pos = _plain_strings(data, pos)
    m.end = pos + 4
    return m


def _plain_strings(data, pos: int) -> tuple[list[str], int]:
    """A CDR sequence of strings, decoded without the name cache (error texts vary)."""
    pos += -pos % 4
    (count,) = _U32.unpack_from(data, pos)
    if count * 4 > len(data) - pos - 4:
        raise WireError(f"sequence of {count} strings")
    pos += 4
    out = []
    for _ in range(count):
        text, pos = _string(data, pos)
        out.append(text)
    return out, pos


def fill_iteration_record(msg, rec: Mapping, run_id: str, sequence: int):
    """Fill an IterationRecord (header stamped by the caller) from a driver iteration record dict."""
    msg.run_id, msg.sequence, msg.iteration = run_id, int(sequence), int(rec["iteration"])
    msg.formulation, msg.optimizer = str(rec.get("formulation", "")), str(rec.get("optimizer", ""))
    to_named_array({k: np.array([float(v)]) for k, v in rec["design"].items()}, msg.design)
    msg.objective_name, msg.objective = str(rec.get("objective_name", "")), float(rec["objective"])
    to_named_array({k: np.array([float(v)]) for k, v in rec.get("constraints", {}).items()}, msg.constraints)
    msg.max_violation = float(rec.get("max_violation", 0.0))
    msg.feasible = bool(rec.get("feasible", False))
    msg.mda_evaluations = int(rec.get("mda_evaluations", 0))
    counts = rec.get("discipline_evaluations", {})
    msg.discipline_names = list(counts)
    msg.discipline_evaluations = [int(v) for v in counts.values()]
    msg.wall_time_s = float(rec.get("wall_time_s", 0.0))
    return msg


class _Order:
    __slots__ = ("header", "run_id", "sequence", "raw")


@_decoding
def iteration_order(data) -> _Order:
    """The header, ``run_id`` and ``sequence`` of an IterationRecord's CDR bytes (the fields it starts
    with), without decoding the rest: what the recorder checks a record's order with."""
    m = _Order()
    m.header, pos = _header(data, 0)
    m.run_id, pos = _string(data, pos)
    pos += -pos % 8
    (m.sequence,) = struct.unpack_from("<Q", data, pos)
    return m
