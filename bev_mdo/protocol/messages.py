"""The message types, generated at import from the .msg files by rosbags' typesys.

The layout of every bev_mdo message is written once, in ``msg_defs/msg/*.msg`` (shipped inside the
installed package as ``bev_mdo/protocol/msg/``). rosbags reads that text and generates a dataclass
and a CDR (de)serialiser per type; this module keeps the compiled functions and calls them directly.
The bytes are plain CDR (XCDR1, little endian, the encapsulation rmw_fastrtps uses), the same bytes
rclpy's serialiser gives for the generated ROS classes, so nodes publish and take raw bytes
(``raw=True`` subscriptions, ``Publisher.publish(bytes)``) and bags written by either read back.
No rclpy import here.
"""
from __future__ import annotations

import re
import struct
import threading
from pathlib import Path

import numpy as np
import rosbags.serde.cdr as _cdr
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

PACKAGE = "bev_mdo_msgs"
_HERE = Path(__file__).resolve().parent
# installed: shipped beside this module (setup.py copies them); a source checkout: msg_defs/msg
MSG_DIR = next((d for d in (_HERE / "msg", _HERE.parents[1] / "msg_defs" / "msg") if d.is_dir()), _HERE / "msg")


_ENCAPSULATION = b"\x00\x01\x00\x00"  # CDR_LE
_rosbags_compile = _cdr.compile_lines


class WireError(ValueError):
    """Bytes that are not a well-formed message of the expected type, or a batch that is malformed."""


def type_name(name: str) -> str:
    """``EvaluationRequest`` -> ``bev_mdo_msgs/msg/EvaluationRequest``."""
    return f"{PACKAGE}/msg/{name}"


def msg_text(name: str) -> str:
    """The .msg text of one of bev_mdo's types (``EvaluationRequest`` or its full type name)."""
    return (MSG_DIR / f"{name.rsplit('/', 1)[-1]}.msg").read_text(encoding="utf-8")


def _store():
    store = get_typestore(Stores.ROS2_JAZZY)  # std_msgs/Header and builtin_interfaces/Time come from here

    types = {}
    for path in sorted(MSG_DIR.glob("*.msg")):
        types.update(get_types_from_msg(path.read_text(encoding="utf-8"), type_name(path.stem)))
    if not types:
        raise ImportError(f"no message definitions (*.msg) in {MSG_DIR}")
    store.register(types)
    return store


STORE = _store()
NAMES = tuple(sorted(p.stem for p in MSG_DIR.glob("*.msg")))

NamedArray = STORE.types[type_name("NamedArray")]
EvaluationRequest = STORE.types[type_name("EvaluationRequest")]
EvaluationResult = STORE.types[type_name("EvaluationResult")]
IterationRecord = STORE.types[type_name("IterationRecord")]
DisciplineInfo = STORE.types[type_name("DisciplineInfo")]
ParetoFront = STORE.types[type_name("ParetoFront")]
Header = STORE.types["std_msgs/msg/Header"]
Time = STORE.types["builtin_interfaces/msg/Time"]


# -- string sequences (a batch's column names, an MDA's disciplines) through a cache ---------------------
# rosbags' generated code sizes, packs and unpacks a string[] field item by item: some 30 strings per
# evaluation message, most of its cost, the same few lists in every message of a run. The generated
# text is kept but for those loops, which call these three helpers instead; the bytes are the same.
# A sequence's count is always at a multiple of 4 (CDR), so its bytes from there are those of the list.
_STRING_BYTES: dict[tuple, bytes] = {}  # tuple of strings -> their CDR bytes (count included)
_STRING_LISTS: dict[tuple, tuple] = {}  # (count, first 64 bytes after it) -> (the bytes after the count, strings)
_STRINGS_MAX = 4096  # entries of each (a run has a few dozen lists; point errors' reasons vary)
_U32 = struct.Struct("<I")


def _string_bytes(items) -> bytes:
    key = tuple(items)
    got = _STRING_BYTES.get(key)
    if got is None:
        out = bytearray(_U32.pack(len(key)))
        for item in key:
            out += b"\0" * (-len(out) % 4)
            data = item.encode()
            out += _U32.pack(len(data) + 1) + data + b"\0"
        if len(_STRING_BYTES) >= _STRINGS_MAX:
            _STRING_BYTES.clear()
        got = _STRING_BYTES[key] = bytes(out)
    return got


def _size_strings(pos: int, items) -> int:
    """The generated size function's step over a string[] field: `pos` after it (from its count)."""
    return pos + len(_string_bytes(items))


def _put_strings(rawdata, pos: int, items) -> int:
    """The generated serialiser's step over a string[] field (from its count): `pos` after it."""
    data = _string_bytes(items)
    end = pos + len(data)
    rawdata[pos:end] = data
    return end


def _get_strings(rawdata, pos: int, size: int) -> tuple[list, int]:
    """The generated deserialiser's step over the `size` strings of a string[] field (after its count,
    which it has checked): (the strings, `pos` after them). Bytes equal to a list seen before (found by
    their first 64 bytes, then compared whole) are that list; others are checked as rosbags checks
    each string (length within the bytes, terminated) and decoded."""
    head = (size, bytes(rawdata[pos:pos + 64]))
    seen = _STRING_LISTS.get(head)
    if seen is not None and rawdata[pos:pos + len(seen[0])] == seen[0]:
        return list(seen[1]), pos + len(seen[0])
    start, n, got = pos, len(rawdata), []
    unpack = _U32.unpack_from
    for _ in range(size):
        pos = (pos + 3) & -4
        length = unpack(rawdata, pos)[0]
        end = pos + 4 + length
        if length < 1 or end > n or rawdata[end - 1] != 0:
            raise SerdeError(f"Invalid string of length {length} at offset {pos}.")
        got.append(bytes(rawdata[pos + 4:end - 1]).decode())
        pos = end
    if len(_STRING_LISTS) >= _STRINGS_MAX:
        _STRING_LISTS.clear()
    _STRING_LISTS[head] = (bytes(rawdata[start:pos]), tuple(got))
    return got, pos


_STRING_LOOPS = (  # (rosbags' generated loop over a string[] field, the call that replaces it)
    (re.compile(r"^( +)pos \+= 4\n\1for val in (message\.\w+):\n\1  pos = \(pos \+ 4 - 1\) & -4\n"
                r"\1  pos \+= 4 \+ len\(val\.encode\(\)\) \+ 1\n", re.M),
     r"\1pos = _size_strings(pos, \2)\n"),
    (re.compile(r"^( +)pack_int32_le\(rawdata, pos, len\(val\)\)\n\1pos \+= 4\n\1for item in val:\n"
                r"\1  bval = memoryview\(item\.encode\(\)\)\n\1  length = len\(bval\) \+ 1\n"
                r"\1  pos = \(pos \+ 4 - 1\) & -4\n\1  pack_int32_le\(rawdata, pos, length\)\n\1  pos \+= 4\n"
                r"\1  rawdata\[pos:pos \+ length - 1\] = bval\n\1  pos \+= length\n", re.M),
     r"\1pos = _put_strings(rawdata, pos, val)\n"),
    (re.compile(r"^( +)value = \[\]\n\1for _ in range\(size\):\n\1  pos = \(pos \+ 4 - 1\) & -4\n"
                r"\1  length = unpack_uint32_le\(rawdata, pos\)\[0\]\n"
                r"\1  check_string\(rawdata, pos, length, cdr=True\)\n"
                r"\1  value\.append\(bytes\(rawdata\[pos \+ 4:pos \+ 4 \+ length - 1\]\)\.decode\(\)\)\n"
                r"\1  pos \+= 4 \+ length\n", re.M),
     r"\1value, pos = _get_strings(rawdata, pos, size)\n"),
)


def _compile_lines(lines):
    """rosbags' compile step, its string[] loops replaced by the cached helpers above."""
    text = "\n".join(lines) + "\n"
    for loop, call in _STRING_LOOPS:
        text = loop.sub(call, text)
    module = _rosbags_compile([text])
    module._size_strings, module._put_strings, module._get_strings = _size_strings, _put_strings, _get_strings
    return module


class _Lookup:
    """What the generated functions are handed as ``typestore``: a nested type's compiled functions
    by a plain dict lookup (``Typestore.get_msgdef`` checks and fills its cache on every call, and the
    generated code calls it once per nested message field). Every nested type is compiled up front,
    with its string[] loops through the cache above."""

    __slots__ = ("get_msgdef", "max_sequence_length")

    def __init__(self, store):
        _cdr.compile_lines = _compile_lines
        try:
            for name in list(store.fielddefs):
                store.get_msgdef(name)
        finally:
            _cdr.compile_lines = _rosbags_compile
        self.get_msgdef = store.cache.__getitem__
        self.max_sequence_length = store.max_sequence_length


class _Codec:
    """The compiled CDR functions of one type (what ``Typestore.serialize_cdr`` looks up per call)."""

    __slots__ = ("typename", "cls", "getsize", "serialize", "deserialize")

    def __init__(self, typename: str):
        d = STORE.get_msgdef(typename)
        self.typename, self.cls = typename, d.cls
        self.getsize, self.serialize, self.deserialize = d.getsize_cdr, d.serialize_cdr_le, d.deserialize_cdr_le


_LOOKUP = _Lookup(STORE)
_CODECS: dict[type, _Codec] = {}
_BY_NAME: dict[str, _Codec] = {}


def codec(cls_or_name) -> _Codec:
    """The codec of a generated class or of a type name (``EvaluationRequest`` or ``pkg/msg/Type``)."""
    c = _CODECS.get(cls_or_name) if isinstance(cls_or_name, type) else _BY_NAME.get(cls_or_name)
    if c is None:
        name = cls_or_name.__msgtype__ if isinstance(cls_or_name, type) else cls_or_name
        c = _Codec(name if "/" in name else type_name(name))
        _CODECS[c.cls] = c
        _BY_NAME[cls_or_name if isinstance(cls_or_name, str) else name] = c
    return c


def encode(msg) -> bytearray:
    """CDR bytes (encapsulation included) of a generated message."""
    c = _CODECS.get(type(msg))
    if c is None:
        msg = to_protocol(msg)
        c = codec(type(msg))
    try:
        return _encode(c, msg)
    except (AttributeError, TypeError):  # a numeric sequence given as a list (the codec wants numpy arrays)
        return _encode(c, _convert(msg, c.typename))


class _Scratch(threading.local):
    """A zeroed buffer per thread that a message is serialised into without sizing it first (the
    generated size function walks the whole message again); a message that does not fit is sized
    and serialised the usual way."""

    def __init__(self):
        self.buf = memoryview(bytearray(1 << 16))


_SCRATCH = _Scratch()


def _encode(c: _Codec, msg) -> bytearray:
    scratch = _SCRATCH.buf
    try:
        end = c.serialize(scratch, 0, msg, _LOOKUP)
    except (ValueError, IndexError, struct.error):  # it does not fit
        end = -1
    except BaseException:
        scratch[:] = bytes(len(scratch))  # partly written: zeroed again (padding is never written)
        raise
    if end >= 0:
        out = bytearray(_ENCAPSULATION)
        out += scratch[:end]
        scratch[:end] = bytes(end)
        return out
    scratch[:] = bytes(len(scratch))
    out = bytearray(4 + c.getsize(0, msg, _LOOKUP))
    out[:4] = _ENCAPSULATION
    c.serialize(memoryview(out)[4:], 0, msg, _LOOKUP)
    return out


def decode(data, cls):
    """A message of generated class (or type name) ``cls`` from CDR bytes; WireError if they are not
    one. The message keeps the bytes (``raw``) and where they end (``end``, before any zero padding DDS
    adds): what a signature is checked against (signing.py)."""
    c = _CODECS.get(cls) or codec(cls)
    if len(data) < 4 or data[0] != 0 or data[1] != 1:
        raise WireError("not little-endian CDR")
    try:
        msg, pos = c.deserialize(memoryview(data)[4:], 0, c.cls, _LOOKUP)
    except (SerdeError, struct.error, UnicodeDecodeError, ValueError, IndexError, TypeError) as exc:
        raise WireError(f"malformed {c.typename.rsplit('/', 1)[-1]} ({exc})") from None
    if pos + 4 > len(data):
        raise WireError("message truncated")
    msg.raw, msg.end = data, pos + 4
    return msg


def _prefix_codec(typename: str, last: str) -> _Codec:
    """A codec of the fields of ``typename`` up to ``last`` (included): a type made from the
    generated field list (not written by hand), read where a full decode is not needed."""
    name = f"{typename}Upto{last.title().replace('_', '')}"
    if name not in STORE.fielddefs:
        consts, fields = STORE.fielddefs[typename][:2]
        k = [f[0] for f in fields].index(last)
        STORE.register({name: ([], fields[:k + 1])})
    return codec(name)


def field_offset(msg, field: str) -> int:
    """Where ``field`` (a string field) of ``msg`` starts in its CDR bytes (encapsulation included):
    the size of the fields before it, from rosbags' generated size function, aligned to 4."""
    typename = type(msg).__msgtype__
    c = _BEFORE.get((typename, field))
    if c is None:
        fields = [f[0] for f in STORE.fielddefs[typename][1]]
        k = fields.index(field)
        c = _BEFORE[(typename, field)] = _prefix_codec(typename, fields[k - 1]) if k else None
    pos = c.getsize(0, msg, _LOOKUP) if c is not None else 0
    return 4 + pos + (-pos % 4)


_BEFORE: dict[tuple, _Codec | None] = {}


def head(data, name: str, last: str):
    """The fields of message type ``name`` up to ``last`` from the start of its CDR bytes (the rest
    is not decoded); WireError if the bytes are too short or malformed."""
    return decode(data, _prefix_codec(type_name(name), last).cls)


# Messages that name their run right after their header (``string run_id``): filtered by run.
RUN_TAGGED = frozenset({"bev_mdo_msgs/msg/EvaluationRequest", "bev_mdo_msgs/msg/EvaluationResult",
                        "bev_mdo_msgs/msg/IterationRecord", "bev_mdo_msgs/msg/ParetoFront"})


def run_of(data) -> str | None:
    """The ``run_id`` of a RUN_TAGGED message from its CDR bytes (each of them starts with a header and
    its run id, so the fields up to ``run_id`` of one of them decode it); None if the bytes do not hold one."""
    try:
        return head(data, "EvaluationRequest", "run_id").run_id or None
    except WireError:
        return None


def stats_run_of(data) -> str | None:
    """The ``run_id`` in a node's counters (``/bev_mdo/node_stats``: a std_msgs/String of JSON,
    ros/discipline_node.publish_stats) from its CDR bytes; None if they name none (a node bound to no run)
    or are not such JSON."""
    import json

    try:
        run = json.loads(decode(data, "std_msgs/msg/String").data).get("run_id")
    except (WireError, ValueError, AttributeError):  # not a String, not JSON, not a JSON object
        return None
    return run if isinstance(run, str) and run else None


# -- new messages, every field at its default (rosbags' dataclasses take every field) -------------------
_DEFAULTS = {"string": "", "bool": False, "float32": 0.0, "float64": 0.0}
_ARRAY_DTYPES = {"bool": np.bool_, "uint8": np.uint8, "uint32": np.uint32, "uint64": np.uint64,
                 "int32": np.int32, "int64": np.int64, "float32": np.float32, "float64": np.float64}


def new(cls, **fields):
    """A message of generated class ``cls`` with the given fields, every other field at its default
    (0, "", empty sequences, nested messages new); the defaults follow the generated field list."""
    made = _MAKERS.get(cls)
    if made is None:
        defaults = [(fname, _default(desc)) for fname, desc in STORE.fielddefs[cls.__msgtype__][1]]
        made = _MAKERS[cls] = ({f: d for f, d in defaults if not callable(d)},
                               [(f, d) for f, d in defaults if callable(d)])
    values, makers = made
    msg = object.__new__(cls)  # the dataclass's __init__ would only assign these, one by one
    d = msg.__dict__
    d.update(values)
    for fname, make in makers:
        d[fname] = make()
    d.update(fields)
    return msg


_MAKERS: dict[type, list] = {}


def _empty(dtype) -> np.ndarray:
    """A shared empty array (read-only: a field holding it is replaced, never written into)."""
    a = np.zeros(0, dtype=dtype)
    a.flags.writeable = False
    return a


def _default(desc):
    """The default of a field: a value (immutable) or a function that makes one (a new list or message)."""
    kind = desc[0]
    if kind == 2:  # a nested message
        nested = STORE.types[desc[1]]
        return lambda: new(nested)
    if kind == 1:  # a primitive
        return _DEFAULTS.get(desc[1][0], 0)
    sub = desc[1][0]
    if sub[0] == 1 and sub[1][0] in _ARRAY_DTYPES:
        return _empty(_ARRAY_DTYPES[sub[1][0]])
    return list


def to_protocol(msg):
    """The generated message of this module with the fields of ``msg``: one of these already (returned
    as it is), or a message object of the same type from elsewhere (rclpy's generated classes: the
    field list followed is the generated one, and sequences become numpy arrays where they are numbers)."""
    if type(msg) in _CODECS or hasattr(type(msg), "__msgtype__"):
        return msg
    cls = type(msg)
    name = f"{cls.__module__.split('.')[0]}/msg/{cls.__name__}"
    if name not in STORE.types:
        raise WireError(f"{cls.__module__}.{cls.__name__} is not a message type of this protocol")
    return _convert(msg, name)


def _convert(msg, typename: str):
    values = {}
    for fname, desc in STORE.fielddefs[typename][1]:
        v = getattr(msg, fname)
        if desc[0] == 2:
            v = _convert(v, desc[1])
        elif desc[0] != 1:
            sub = desc[1][0]
            if sub[0] == 1 and sub[1][0] in _ARRAY_DTYPES:
                v = np.asarray(v, dtype=_ARRAY_DTYPES[sub[1][0]])
            elif sub[0] == 2:
                v = [_convert(x, sub[1]) for x in v]
            else:
                v = list(v)
        values[fname] = v
    return STORE.types[typename](**values)
