"""The partials fields (EvaluationRequest.partials, EvaluationResult.partials) and vector element names
on the wire, against rclpy's own serialisation, and in the HMAC canonical bytes."""
from __future__ import annotations

import array

import numpy as np
import pytest


from rclpy.serialization import deserialize_message, serialize_message  # noqa: E402

from bev_mdo import protocol  # noqa: E402
from bev_mdo.protocol.signing import Signer  # noqa: E402
from bev_mdo_msgs.msg import EvaluationRequest, EvaluationResult  # noqa: E402


@pytest.mark.parametrize("asked", [False, True])
def test_request_partials_flag_round_trips_both_ways(asked):
    m = EvaluationRequest()
    m.run_id, m.evaluation_id, m.discipline, m.signature = "r", 3, "structure", "s"
    m.inputs.names, m.inputs.batch_size, m.inputs.values = ["x_shared[0]", "x"], 2, array.array("d", [1, 2, 3, 4])
    m.partials = asked
    d = protocol.decode_request(serialize_message(m))
    assert d.partials is asked and d.inputs.names == ["x_shared[0]", "x"]
    assert protocol.from_named_array(d.inputs)["x_shared[0]"].tolist() == [1, 2]
    assert deserialize_message(protocol.encode_request(d), EvaluationRequest) == m


def test_result_partials_round_trip_both_ways_and_decode_to_pairs():
    part = {("y_1[0]", "x_shared[3]"): np.array([1.5, -2.0]), ("y_1[1]", "x"): np.array([0.0, 4.0])}
    r = protocol.result()
    r.run_id, r.evaluation_id, r.discipline = "r", 4, "structure"
    r.point_ok = np.array([True, True])
    r.outputs = protocol.batch({"y_1[0]": np.ones(2), "y_1[1]": np.zeros(2)})
    r.partials = protocol.partials_batch(part, 2)
    data = protocol.encode_result(r)
    m = deserialize_message(data, EvaluationResult)
    assert list(m.partials.names) == ["y_1[0]/x_shared[3]", "y_1[1]/x"] and m.partials.batch_size == 2
    again = protocol.decode_result(serialize_message(m))  # rclpy's bytes (padding may differ) decode the same
    assert list(again.partials.names) == list(m.partials.names)
    np.testing.assert_array_equal(again.partials.values, np.asarray(m.partials.values))
    back = protocol.partials_of(protocol.decode_result(data).partials, 2)
    assert back.keys() == part.keys() and all(np.array_equal(back[k], part[k]) for k in part)
    # asked, but the discipline has none: a block of the batch size with no column
    none = protocol.partials_batch({}, 2)
    assert (none.batch_size, list(none.names)) == (2, []) and protocol.partials_of(none, 2) is None
    assert protocol.partials_batch(None, 2).batch_size == 0


@pytest.mark.parametrize("name", ["y/", "/x", "y/x/z", "y[0]/x[", "a b/x"])
def test_malformed_partial_names_are_wire_errors(name):
    b = protocol.NamedArray([name], 1, np.zeros(1))
    with pytest.raises(protocol.WireError):
        protocol.partials_of(b, 1)


def test_element_names_pass_but_other_brackets_do_not():
    ok = protocol.to_named_array({"x_shared[5]": np.ones(1)})
    assert list(protocol.from_named_array(ok)) == ["x_shared[5]"]
    for bad in ["x[-1]", "x[a]", "x[1][2]", "[1]"]:
        with pytest.raises(protocol.WireError):
            protocol.from_named_array(protocol.to_named_array({bad: np.ones(1)}))


def test_signature_covers_the_partials():
    s = Signer(b"k" * 32)
    req = protocol.request("r", 1, "d")
    req.inputs = protocol.batch({"x": np.ones(1)})
    s.sign_request(req)
    req.partials = True
    assert s.verify_request(req) == "forged"
    res = protocol.result()
    res.run_id, res.evaluation_id, res.discipline = "r", 1, "d"
    res.partials = protocol.partials_batch({("y", "x"): np.ones(1)}, 1)
    s.sign_result(res)
    res.partials = protocol.partials_batch({("y", "x"): np.full(1, 2.0)}, 1)
    assert s.verify_result(res) == "forged"
