"""Message authentication with a shared key: HMAC-SHA256 from the standard library.

The pip build of Fast DDS has no DDS-Security, so SROS2 cannot be enforced with it.
With ``ros.sign_key_file`` set, every EvaluationRequest and EvaluationResult carries
``signature = hex(HMAC-SHA256(key, canonical bytes))``. The canonical bytes are a
fixed, length-prefixed encoding of every field the receiver acts on (run id,
evaluation id, attempt, discipline, names, batch size, the float64 values as
little-endian bytes, status / error / point_ok / point errors for results) and the header stamp.

A receiver drops and counts a message that is
- ``unsigned``: no signature;
- ``forged``: the signature does not match (wrong key, or any signed field changed);
- ``expired``: its stamp is further than ``window_s`` from the receiver's clock
  (either way, so a far-future stamp cannot pre-date a replay);
- ``replayed``: an identical signed message was already accepted within the window.
A retry re-sends an evaluation with ``attempt + 1`` and a fresh stamp, so it has a new
signature and is not a replay. The key itself is only ever read from the file: the
config, logs and bags hold the path.

Discipline declarations (DisciplineInfo) and iteration records (IterationRecord) are signed
too and verified by MAC only (``unsigned`` / ``forged``; no freshness window: declarations
are TRANSIENT_LOCAL and records are verified again offline, from a bag). ``bev-mdo optimize``
signs by default with a fresh per-run key file (``new_key_file``, mode 0600); see
docs/security.md for what is and is not protected.
"""
from __future__ import annotations

import hashlib
import hmac
import os
import struct
import time
from collections import OrderedDict
from pathlib import Path
from typing import Callable

import numpy as np

MIN_KEY_BYTES = 16
REASONS = ("unsigned", "forged", "expired", "replayed")
_REQ_TAG = b"bev_mdo/EvaluationRequest/v1\0"
_RES_TAG = b"bev_mdo/EvaluationResult/v1\0"
_INFO_TAG = b"bev_mdo/DisciplineInfo/v1\0"
_ITER_TAG = b"bev_mdo/IterationRecord/v1\0"


class AuthError(ValueError):
    """The key file is missing, unreadable or too short (the message never shows the key)."""


def new_key_file(directory: str | os.PathLike, name: str = "sign.key") -> str:
    """Write a fresh random 32-byte key (hex) to ``directory/name``, created with mode 0600
    (never readable by other users, not even for a moment); returns its path."""
    import secrets

    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    path = d / name
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "w") as f:
        f.write(secrets.token_hex(32))
    return str(path.resolve())


def read_key(path: str | os.PathLike) -> bytes:
    """The shared key: the file's bytes without surrounding whitespace (>= 16 bytes)."""
    p = Path(path)
    try:
        key = p.read_bytes().strip()
    except OSError as exc:
        raise AuthError(f"ros.sign_key_file {str(p)!r}: cannot read ({exc.strerror})") from None
    if len(key) < MIN_KEY_BYTES:
        raise AuthError(f"ros.sign_key_file {str(p)!r}: key shorter than {MIN_KEY_BYTES} bytes")
    return key


def _s(out: list[bytes], text: str) -> None:
    b = text.encode("utf-8", "surrogatepass")
    out.append(struct.pack("<I", len(b)))
    out.append(b)


def _named(out: list[bytes], arr) -> None:
    names = list(arr.names)
    out.append(struct.pack("<I", len(names)))
    for k in names:
        _s(out, k)
    out.append(struct.pack("<I", int(arr.batch_size)))
    vals = np.asarray(arr.values, dtype="<f8").tobytes() if len(arr.values) else b""
    out.append(struct.pack("<Q", len(vals)))
    out.append(vals)


def _stamp(out: list[bytes], header) -> None:
    out.append(struct.pack("<iI", int(header.stamp.sec), int(header.stamp.nanosec)))
    _s(out, header.frame_id)


def request_bytes(msg) -> bytes:
    """Canonical bytes of an EvaluationRequest (everything but the signature)."""
    out = [_REQ_TAG]
    _stamp(out, msg.header)
    _s(out, msg.run_id)
    out.append(struct.pack("<QQII", int(msg.evaluation_id), int(msg.sequence), int(msg.iteration), int(msg.attempt)))
    _s(out, msg.discipline)
    _named(out, msg.inputs)
    out.append(struct.pack("<I", len(msg.flow)))
    for name in msg.flow:
        _s(out, name)
    out.append(struct.pack("<B", int(bool(getattr(msg, "partials", False)))))
    return b"".join(out)


def result_bytes(msg) -> bytes:
    """Canonical bytes of an EvaluationResult (everything but the signature)."""
    out = [_RES_TAG]
    _stamp(out, msg.header)
    _s(out, msg.run_id)
    out.append(struct.pack("<QQ", int(msg.evaluation_id), int(msg.sequence)))
    _s(out, msg.discipline)
    _s(out, msg.instance)
    out.append(struct.pack("<B", int(msg.status)))
    _s(out, msg.error)
    ok = bytes(bool(b) for b in msg.point_ok)
    out.append(struct.pack("<I", len(ok)))
    out.append(ok)
    _named(out, msg.outputs)
    out.append(struct.pack("<d", float(msg.compute_time_s)))
    out.append(struct.pack("<I", len(msg.flow)))
    for name in msg.flow:
        _s(out, name)
    _named(out, msg.partials)
    points = np.asarray(getattr(msg, "error_points", ()), dtype="<u4")  # a bag's older schema has none
    out.append(struct.pack("<I", points.size))
    out.append(points.tobytes())
    _texts(out, getattr(msg, "error_reasons", ()))
    _texts(out, getattr(msg, "error_inputs", ()))
    return b"".join(out)


def _texts(out: list[bytes], items) -> None:
    items = list(items)
    out.append(struct.pack("<I", len(items)))
    for t in items:
        _s(out, t)


def info_bytes(msg) -> bytes:
    """Canonical bytes of a DisciplineInfo (everything but the signature)."""
    out = [_INFO_TAG]
    _stamp(out, msg.header)
    for text in (msg.discipline, msg.instance, msg.class_name):
        _s(out, text)
    for seq in (msg.inputs, msg.outputs, msg.parameters):
        _texts(out, seq)
    _s(out, msg.version)
    _texts(out, msg.coupling_inputs)
    _texts(out, msg.coupling_sources)
    for text in (msg.run_id, msg.fingerprint, msg.effective_config):
        _s(out, text)
    return b"".join(out)


def iteration_bytes(msg) -> bytes:
    """Canonical bytes of an IterationRecord (everything but the signature)."""
    out = [_ITER_TAG]
    _stamp(out, msg.header)
    _s(out, msg.run_id)
    out.append(struct.pack("<QI", int(msg.sequence), int(msg.iteration)))
    for text in (msg.formulation, msg.optimizer):
        _s(out, text)
    _named(out, msg.design)
    _s(out, msg.objective_name)
    out.append(struct.pack("<d", float(msg.objective)))
    _named(out, msg.constraints)
    out.append(struct.pack("<dBQ", float(msg.max_violation), bool(msg.feasible), int(msg.mda_evaluations)))
    _texts(out, msg.discipline_names)
    ev = [int(v) for v in msg.discipline_evaluations]
    out.append(struct.pack(f"<I{len(ev)}Q", len(ev), *ev))
    out.append(struct.pack("<d", float(msg.wall_time_s)))
    return b"".join(out)


class Signer:
    """Signs outgoing and verifies incoming requests and results with one shared key."""

    def __init__(self, key: bytes, window_s: float = 30.0, clock_ns: Callable[[], int] = time.time_ns,
                 max_seen: int = 1_000_000):
        if len(key) < MIN_KEY_BYTES:
            raise AuthError(f"key shorter than {MIN_KEY_BYTES} bytes")
        self._key = key
        self.window_ns = int(window_s * 1e9)
        self._clock = clock_ns
        self._seen: OrderedDict[tuple, int] = OrderedDict()  # accepted (kind, ids, signature) -> stamp ns
        self._max_seen = max_seen

    def __repr__(self) -> str:  # never show the key
        return f"Signer(window_s={self.window_ns / 1e9:g})"

    @classmethod
    def from_ros(cls, ros) -> "Signer | None":
        """A Signer from a validated `ros:` section, or None when signing is off."""
        path = (ros or {}).get("sign_key_file") or ""
        if not path:
            return None
        return cls(read_key(path), float((ros or {}).get("sign_window_s", 30.0)))

    def _mac(self, data: bytes) -> str:
        return hmac.new(self._key, data, hashlib.sha256).hexdigest()

    def sign_request(self, msg) -> None:
        msg.signature = self._mac(request_bytes(msg))

    def sign_result(self, msg) -> None:
        msg.signature = self._mac(result_bytes(msg))

    def sign_info(self, msg) -> None:
        msg.signature = self._mac(info_bytes(msg))

    def sign_iteration(self, msg) -> None:
        msg.signature = self._mac(iteration_bytes(msg))

    def verify_info(self, msg) -> str | None:
        """None if the declaration is authentic, else "unsigned" or "forged". No freshness window:
        declarations are TRANSIENT_LOCAL, a late coordinator gets old ones, and a replayed
        genuine declaration says nothing new."""
        return self._mac_only(msg, info_bytes)

    def verify_iteration(self, msg) -> str | None:
        """None if the iteration record is authentic, else "unsigned" or "forged" (also offline,
        on records read back from a bag: no freshness window)."""
        return self._mac_only(msg, iteration_bytes)

    def _mac_only(self, msg, encode) -> str | None:
        sig = msg.signature
        if not sig:
            return "unsigned"
        if len(sig) != 64 or not hmac.compare_digest(sig, self._mac(encode(msg))):
            return "forged"
        return None

    def verify_request(self, msg) -> str | None:
        """None if the request is authentic and fresh, else the reason (one of REASONS)."""
        return self._verify(msg, request_bytes, ("req", msg.run_id, int(msg.evaluation_id), msg.discipline))

    def verify_result(self, msg) -> str | None:
        """None if the result is authentic and fresh, else the reason (one of REASONS)."""
        return self._verify(msg, result_bytes, ("res", msg.run_id, int(msg.evaluation_id), msg.discipline))

    def _verify(self, msg, encode, ids: tuple) -> str | None:
        sig = msg.signature
        if not sig:
            return "unsigned"
        if len(sig) != 64 or not hmac.compare_digest(sig, self._mac(encode(msg))):
            return "forged"
        t = int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)
        now = self._clock()
        if abs(now - t) > self.window_ns:
            return "expired"
        self._prune(now)
        key = (*ids, sig)
        if key in self._seen:
            return "replayed"
        self._seen[key] = t
        return None

    def _prune(self, now: int) -> None:
        # Entries older than the window can go: such a message would be rejected as expired.
        # Insertion order is close to stamp order; stop at the first entry still in the window.
        seen = self._seen
        while seen:
            k, t = next(iter(seen.items()))
            if now - t > self.window_ns or len(seen) > self._max_seen:
                seen.popitem(last=False)
            else:
                break


def with_run_key(config: dict, directory: Path) -> dict:
    """Signing on by default: without a configured ``ros.sign_key_file`` (and unless
    ``ros.signing: false``) a fresh random key is written to ``<directory>/sign.key`` (mode 0600;
    callers pass a directory outside the bag); the resolved config that the nodes and the recorder read names its path
    only, so the key is never on a command line, in the environment or in the bag."""
    ros = dict(config.get("ros") or {})
    if ros.get("sign_key_file") or not ros.get("signing", True):
        return config
    ros["sign_key_file"] = new_key_file(directory)
    return {**config, "ros": ros}
