"""The protocol's generated CDR codec against rclpy's own serialisation of the generated messages."""
from __future__ import annotations

import array

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st


from rclpy.serialization import deserialize_message, serialize_message  # noqa: E402

from bev_mdo.mdo.discipline import PointError  # noqa: E402
from bev_mdo import protocol  # noqa: E402
from bev_mdo_msgs.msg import EvaluationRequest, EvaluationResult  # noqa: E402

text = st.text(st.characters(codec="utf-8", exclude_characters="\x00"), max_size=20)
names = st.lists(st.from_regex(r"[a-z_][a-z0-9_]{0,12}", fullmatch=True), max_size=4, unique=True)
u32 = st.integers(0, 2**32 - 1)
u64 = st.integers(0, 2**64 - 1)
floats = st.floats(allow_nan=False, width=64)


@st.composite
def columns(draw):
    cols = draw(names)
    n = draw(st.integers(0, 5))
    values = draw(st.lists(floats, min_size=n * len(cols), max_size=n * len(cols)))
    return cols, n, values


def _fill_header(m, sec, nsec, frame):
    m.header.stamp.sec, m.header.stamp.nanosec, m.header.frame_id = sec, nsec, frame


@settings(max_examples=150, deadline=None)
@given(sec=st.integers(-2**31, 2**31 - 1), nsec=u32, frame=text, run=text, eid=u64, seq=u64, it=u32, att=u32,
       disc=text, cols=columns(), flow=st.lists(text, max_size=4), sig=text)
def test_request_round_trips_both_ways(sec, nsec, frame, run, eid, seq, it, att, disc, cols, flow, sig):
    m = EvaluationRequest()
    _fill_header(m, sec, nsec, frame)
    m.run_id, m.evaluation_id, m.sequence, m.iteration, m.attempt, m.discipline = run, eid, seq, it, att, disc
    m.inputs.names, m.inputs.batch_size, m.inputs.values = cols[0], cols[1], array.array("d", cols[2])
    m.flow, m.signature = flow, sig
    d = protocol.decode_request(serialize_message(m))
    assert (d.header.stamp.sec, d.header.stamp.nanosec, d.header.frame_id) == (sec, nsec, frame)
    assert (d.run_id, d.evaluation_id, d.sequence, d.iteration, d.attempt, d.discipline) == (run, eid, seq, it, att,
                                                                                            disc)
    assert (d.inputs.names, d.inputs.batch_size, d.flow, d.signature) == (cols[0], cols[1], flow, sig)
    np.testing.assert_array_equal(d.inputs.values, cols[2])
    assert deserialize_message(protocol.encode_request(d), EvaluationRequest) == m


@settings(max_examples=150, deadline=None)
@given(sec=st.integers(-2**31, 2**31 - 1), nsec=u32, run=text, eid=u64, seq=u64, disc=text, inst=text,
       status=st.integers(0, 255), err=text, ok=st.lists(st.booleans(), max_size=7), cols=columns(),
       t=floats, flow=st.lists(text, max_size=4), sig=text, why=st.lists(st.tuples(u32, text, text), max_size=4))
def test_result_round_trips_both_ways(sec, nsec, run, eid, seq, disc, inst, status, err, ok, cols, t, flow, sig,
                                      why):
    m = EvaluationResult()
    _fill_header(m, sec, nsec, "")
    m.run_id, m.evaluation_id, m.sequence, m.discipline, m.instance = run, eid, seq, disc, inst
    m.status, m.error, m.point_ok = status, err, ok
    m.outputs.names, m.outputs.batch_size, m.outputs.values = cols[0], cols[1], array.array("d", cols[2])
    m.compute_time_s, m.flow, m.signature = t, flow, sig
    m.error_points, m.error_reasons, m.error_inputs = [w[0] for w in why], [w[1] for w in why], [w[2] for w in why]
    d = protocol.decode_result(serialize_message(m))
    assert (d.run_id, d.evaluation_id, d.sequence, d.discipline, d.instance, d.status, d.error) == (
        run, eid, seq, disc, inst, status, err)
    assert d.point_ok.tolist() == ok and d.outputs.names == cols[0] and d.outputs.batch_size == cols[1]
    np.testing.assert_array_equal(d.outputs.values, cols[2])
    assert (d.compute_time_s, d.flow, d.signature) == (t, flow, sig)
    assert list(zip(d.error_points, d.error_reasons, d.error_inputs)) == why
    assert deserialize_message(protocol.encode_result(d), EvaluationResult) == m


def test_a_large_batch_decodes_without_copying_each_column():
    cols = {"a": np.arange(100_000.0), "b": -np.arange(100_000.0)}
    req = protocol.request("run", 7, "energy")
    req.inputs = protocol.batch(cols)
    d = protocol.decode_request(protocol.encode_request(req))
    got = protocol.from_named_array(d.inputs)
    np.testing.assert_array_equal(got["b"], cols["b"])
    assert got["a"].base is not None  # a view into the received buffer


@pytest.mark.parametrize("cut", [0, 3, 10, 40, -9, -1])
def test_truncated_or_foreign_bytes_raise_wire_error(cut):
    req = protocol.request("run", 7, "energy", flow=["energy", "range"])
    req.inputs = protocol.batch({"x": np.ones(3)})
    data = protocol.encode_request(req)
    with pytest.raises(protocol.WireError):
        protocol.decode_request(data[:cut])
    with pytest.raises(protocol.WireError):
        protocol.decode_request(b"\x01\x00\x00\x00" + data[4:])  # big-endian encapsulation is not ours
    with pytest.raises(protocol.WireError):
        protocol.decode_result(data[:cut])


def test_point_errors_travel_as_fields_and_are_checked():
    res = protocol.result()
    res.point_ok = np.array([True, False, False])
    res.outputs = protocol.batch({"y": np.array([1.0, np.nan, np.nan])})
    why = {2: PointError("square: ValueError: x must be >= 0", "x=-1"), 1: PointError("square: non-finite input")}
    protocol.put_point_errors(res, why)
    got = protocol.point_errors_of(protocol.decode_result(protocol.encode_result(res)), 3)
    assert got == why and list(got) == [2, 1]  # order kept: the error text lists them in that order
    for points, reasons in (([3], ["a"]), ([1, 1], ["a", "b"]), ([1], [])):
        res.error_points, res.error_reasons, res.error_inputs = points, reasons, [""] * len(reasons)
        with pytest.raises(protocol.WireError):
            protocol.point_errors_of(protocol.decode_result(protocol.encode_result(res)), 3)
