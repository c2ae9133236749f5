"""The protocol's string[] fields go through a cache (protocol/messages.py): the bytes are those rosbags'
own generated code gives, a decoded list is the caller's own, and bytes that only start like a list seen
before are checked as any other. No ROS processes."""
from __future__ import annotations

import numpy as np
import pytest
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from bev_mdo import protocol
from bev_mdo.protocol import messages


def _plain_store():
    """A typestore of the same .msg files compiled by rosbags as it is (no cached string loops)."""
    store = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for name in messages.NAMES:
        types.update(get_types_from_msg(messages.msg_text(name), messages.type_name(name)))
    store.register(types)
    return store


def _result(names, flow, reasons=()):
    out = protocol.result()
    out.run_id, out.evaluation_id, out.discipline, out.instance = "run-1", 7, "energy", "energy_node"
    out.point_ok = np.ones(3, dtype=bool)
    out.outputs = protocol.batch({k: np.arange(3.0) + i for i, k in enumerate(names)})
    out.flow = list(flow)
    out.error_reasons = list(reasons)
    return out


@pytest.mark.parametrize("names, flow, reasons", [
    (["a"], [], []),
    (["motor_kw", "battery_kwh", "x" * 7, "é_unicode", "y" * 64], ["vehicle_mass", "energy"], ["square: bad"]),
    ([f"column_{i}" for i in range(40)], ["d1", "d22", "d333", "d4444"], ["", "x", "yy", "zzz"]),
])
def test_the_bytes_are_rosbags_own_and_decode_to_the_same_lists(names, flow, reasons):
    plain = _plain_store()
    msg = _result(names, flow, reasons)
    data = protocol.encode_result(msg)
    cls = plain.types[messages.type_name("EvaluationResult")]
    assert data == bytes(plain.serialize_cdr(plain.deserialize_cdr(data, cls.__msgtype__), cls.__msgtype__))
    for _ in range(2):  # decoded, then found in the cache
        got = protocol.decode_result(data)
        assert list(got.outputs.names) == names and list(got.flow) == flow and list(got.error_reasons) == reasons


def test_a_decoded_list_is_the_callers_own():
    data = protocol.encode_result(_result(["p", "q"], ["a", "b"]))
    first = protocol.decode_result(data)
    first.flow.append("changed")
    first.outputs.names[0] = "changed"
    again = protocol.decode_result(data)
    assert list(again.flow) == ["a", "b"] and list(again.outputs.names) == ["p", "q"]


def test_bytes_that_start_like_a_known_list_are_checked():
    names = [f"n{i}" for i in range(30)]  # longer than the 64 bytes the cache is found by
    data = bytearray(protocol.encode_result(_result(names, ["a"])))
    protocol.decode_result(bytes(data))  # now known
    last = bytes(data).index(b"n29\x00")
    bad = bytearray(data)
    bad[last + 3] = ord("x")  # the last name loses its terminator, after the first 64 bytes
    with pytest.raises(protocol.WireError):
        protocol.decode_result(bytes(bad))
    with pytest.raises(protocol.WireError):
        protocol.decode_result(bytes(data[:last + 2]))  # cut inside the list


def test_a_message_larger_than_the_scratch_buffer_and_the_next_small_one_encode_right():
    plain = _plain_store()
    typename = messages.type_name("EvaluationResult")
    big = _result([f"c{i}" for i in range(20)], ["a"])
    big.outputs = protocol.batch({f"c{i}": np.full(5000, i + 0.5) for i in range(20)})  # 800 kB
    long_text = _result(["p"], ["a"], ["r" * 70_000])  # fails in the scratch buffer inside a string
    for msg in (big, _result(["p"], []), long_text, _result(["q", "r"], ["b"])):
        data = protocol.encode_result(msg)
        assert data == bytes(plain.serialize_cdr(plain.deserialize_cdr(data, typename), typename))
