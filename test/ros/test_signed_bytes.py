"""Signing covers the exact bytes that are sent: the MAC of every signed message is
HMAC-SHA256 over its CDR bytes with the signature field empty, so no second encoding exists, and a
change of any byte of a sent message makes it forged (or undecodable). No ROS processes."""
from __future__ import annotations

import hashlib
import hmac
import secrets

import numpy as np
import pytest

from rclpy.serialization import deserialize_message  # noqa: E402

from bev_mdo.mdo.discipline import PointError  # noqa: E402
from bev_mdo.protocol import signing as auth  # noqa: E402
from bev_mdo import protocol  # noqa: E402
from bev_mdo.protocol.signing import Signer  # noqa: E402
from bev_mdo.ros.common import stamp  # noqa: E402
from bev_mdo_msgs.msg import DisciplineInfo, EvaluationRequest, EvaluationResult, IterationRecord  # noqa: E402

KEY = secrets.token_bytes(32)


def _request() -> protocol.EvaluationRequest:
    req = protocol.request("run-1", 7, "energy", flow=["vehicle_mass", "energy"], iteration=3)
    stamp(req.header)
    req.header.frame_id = "energy=0123456789abcdef"
    req.attempt, req.sequence, req.partials = 1, 11, True
    req.inputs = protocol.batch({"vehicle_mass_kg": np.array([1500.0, 1600.0]), "motor_kw": np.array([80.0, 90.0])})
    return req


def _result() -> protocol.EvaluationResult:
    res = protocol.result()
    stamp(res.header)
    res.header.frame_id = "energy=0123456789abcdef"
    res.run_id, res.evaluation_id, res.sequence, res.discipline, res.instance = "run-1", 7, 5, "energy", "/energy_node"
    res.status, res.error = 1, "energy: ValueError: no at point 1"
    res.point_ok = np.array([True, False])
    res.outputs = protocol.batch({"energy_wh_per_km": np.array([120.0, -1.0])})  # no NaN: rclpy messages compare by ==
    res.compute_time_s, res.flow = 0.25, ["vehicle_mass", "energy"]
    res.partials = protocol.partials_batch({("energy_wh_per_km", "motor_kw"): np.array([0.5, 0.0])}, 2)
    protocol.put_point_errors(res, {1: PointError("energy: ValueError: no", "motor_kw=90")})
    return res


def _typed(kind: str, m):
    """The generated rclpy message with the fields of a protocol.EvaluationRequest/Result ``m``, signature empty."""
    data = (protocol.encode_request if kind == "request" else protocol.encode_result)(m)
    msg = deserialize_message(data, EvaluationRequest if kind == "request" else EvaluationResult)
    msg.signature = ""
    return msg


def _info() -> DisciplineInfo:
    msg = DisciplineInfo()
    stamp(msg.header)
    msg.discipline, msg.instance, msg.class_name = "energy", "/energy_node", "bev_mdo.disciplines:Energy"
    msg.inputs, msg.outputs = ["vehicle_mass_kg", "motor_kw"], ["energy_wh_per_km"]
    msg.version, msg.run_id, msg.fingerprint, msg.effective_config = "0.1", "run-1", "0123456789abcdef", "{}"
    msg.coupling_inputs, msg.coupling_sources = ["vehicle_mass_kg"], ["vehicle_mass"]
    return msg


def _record() -> IterationRecord:
    msg = IterationRecord()
    stamp(msg.header)
    msg.run_id, msg.sequence, msg.iteration, msg.formulation, msg.optimizer = "run-1", 4, 3, "mdf", "SLSQP"
    protocol.to_named_array({"motor_kw": np.array([80.0])}, msg.design)
    msg.objective_name, msg.objective = "powertrain_cost_usd", 9000.5
    protocol.to_named_array({"range_km": np.array([150.0])}, msg.constraints)
    msg.max_violation, msg.feasible, msg.mda_evaluations = 0.0, True, 42
    msg.discipline_names, msg.discipline_evaluations = ["energy"], [42]
    msg.wall_time_s = 1.5
    return msg


def _hmac(data: bytes) -> str:
    return hmac.new(KEY, data, hashlib.sha256).hexdigest()


# -- no second encoding -------------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["request", "result"])
def test_the_mac_is_over_the_sent_cdr_bytes_with_the_signature_empty(kind):
    m = _request() if kind == "request" else _result()
    sent = (Signer(KEY).sign_request if kind == "request" else Signer(KEY).sign_result)(m)
    assert len(m.signature) == 64
    decoded = (protocol.decode_request if kind == "request" else protocol.decode_result)(sent)
    at = auth.signature_at(decoded)
    blank = sent[:at] + auth.BLANK_SIGNATURE + sent[at + 69:]  # the bytes as sent, signature emptied
    assert m.signature == _hmac(blank) and decoded.signature == m.signature
    assert sent[at + 4:at + 68].decode() == m.signature
    # those bytes are the message's CDR: rclpy reads them as the same message, signature empty
    typed = _typed(kind, m)
    assert deserialize_message(blank, type(typed)) == typed
    assert deserialize_message(sent, type(typed)).signature == m.signature


@pytest.mark.parametrize("make", [_info, _record])
def test_declarations_and_records_are_signed_over_the_bytes_published(make):
    msg = make()
    sent = (Signer(KEY).sign_info if make is _info else Signer(KEY).sign_iteration)(msg)
    blank = sent[:-69] + auth.BLANK_SIGNATURE  # the signature is these messages' last field
    assert msg.signature == _hmac(blank) and sent[-65:-1].decode() == msg.signature
    assert deserialize_message(sent, type(msg)) == msg
    msg.signature = ""
    assert deserialize_message(blank, type(msg)) == msg
    verify = Signer(KEY).verify_info if make is _info else Signer(KEY).verify_iteration
    assert verify(sent) is None
    assert verify(blank) == "unsigned"


def test_auth_holds_no_encoder_of_its_own():
    """The message layout is the generated codec's alone: signing.py neither packs bytes nor names a message field."""
    import inspect

    src = inspect.getsource(auth)
    assert "struct" not in src and "pack(" not in src
    for field in ("evaluation_id\")", "point_ok", "batch_size", "error_points", "coupling_sources", "objective"):
        assert field not in src, field


# -- one changed byte anywhere: forged -----------------------------------------------------------
@pytest.mark.parametrize("kind", ["request", "result"])
def test_a_flipped_byte_in_any_field_of_a_sent_message_is_forged(kind):
    m = _request() if kind == "request" else _result()
    signer = Signer(KEY)
    sent = (signer.sign_request if kind == "request" else signer.sign_result)(m)
    decode = protocol.decode_request if kind == "request" else protocol.decode_result
    verify = signer.verify_request if kind == "request" else signer.verify_result
    forged, undecodable = set(), set()
    for i in range(len(sent)):
        bad = bytearray(sent)
        bad[i] ^= 0x01
        try:
            msg = decode(bytes(bad))
        except protocol.WireError:  # a length, a NUL, the encapsulation: dropped as malformed
            undecodable.add(i)
            continue
        why = verify(msg)
        assert why == "forged", (i, why)
        forged.add(i)
    assert len(forged) + len(undecodable) == len(sent)
    # every byte of the stamp, of the float64 values, of the signature and of the ids decodes, and is forged
    columns = m.inputs.values if kind == "request" else m.outputs.values
    at = auth.signature_at(decode(sent))
    for start, size in ((4, 8), (sent.index(columns.tobytes()), columns.nbytes), (at + 4, 64),
                        (sent.index(b"run-1\x00"), 5)):
        assert set(range(start, start + size)) <= forged, (start, size)
    assert verify(decode(sent)) is None  # the message as sent verifies (once)
    assert verify(decode(sent)) == "replayed"


@pytest.mark.parametrize("make", [_info, _record])
def test_a_flipped_byte_of_a_declaration_or_record_is_forged(make):
    msg = make()
    signer = Signer(KEY)
    sent = (signer.sign_info if make is _info else signer.sign_iteration)(msg)
    verify = signer.verify_info if make is _info else signer.verify_iteration
    for i in range(len(sent)):
        bad = bytearray(sent)
        bad[i] ^= 0x01
        assert verify(bytes(bad)) == "forged", i


@pytest.mark.parametrize("make", [_request, _result, _info, _record])
def test_zero_padding_dds_adds_to_a_sent_message_still_verifies(make):
    """DDS may deliver a message padded with zeros to a multiple of 4 bytes (seen between
    processes); the signature covers the message as the sender encoded it."""
    signer = Signer(KEY)
    m = make()
    if make in (_request, _result):
        sent = (signer.sign_request if make is _request else signer.sign_result)(m)
        decode = protocol.decode_request if make is _request else protocol.decode_result
        verify = signer.verify_request if make is _request else signer.verify_result
        pad = -len(sent) % 4 or 4  # padding to the next multiple of 4 (a whole word when aligned)
        assert verify(decode(sent + bytes(pad))) is None
    else:
        sent = (signer.sign_info if make is _info else signer.sign_iteration)(m)
        verify = signer.verify_info if make is _info else signer.verify_iteration
        assert len(sent) % 4 == 1
        assert verify(sent + bytes(3)) is None and verify(sent) is None
        assert verify(sent + b"\x00\x00\x01") == "forged"
