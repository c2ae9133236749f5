"""Message authentication with a shared key: HMAC-SHA256 from the standard library.

The pip build of Fast DDS has no DDS-Security, so SROS2 cannot be enforced with it.
With ``ros.sign_key_file`` set, every EvaluationRequest and EvaluationResult carries
``signature = hex(HMAC-SHA256(key, the message's CDR bytes with the signature field empty))``:
the MAC covers exactly the bytes that are sent, every field and every padding byte, and no
second encoding of the message exists (the layout is wire.py's alone). The sender encodes once
with the field empty, MACs, and puts the signature in (wire.encode_request/_result with ``mac``);
the receiver blanks the field in the bytes it received and MACs those (wire.signed_bytes).
DisciplineInfo and IterationRecord are serialised once by rclpy (with the signature empty),
signed, and those bytes are published (rclpy leaves CDR padding bytes as it finds them, so a
second serialisation could differ); their signature is their last field, so a receiver (or
``bev-mdo`` reading a bag) blanks it in the received bytes the same way. This module keeps the
key, the Signer, the freshness and replay window and the reasons.

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

import hmac
import os
import time
from collections import OrderedDict
from pathlib import Path
from typing import Callable

from bev_mdo.ros.wire import (BLANK_SIGNATURE, SIGNATURE_CHARS, encode_request, encode_result, signed,
                              signed_bytes, unsigned_request, unsigned_result)

MIN_KEY_BYTES = 16
REASONS = ("unsigned", "forged", "expired", "replayed")


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


def _tail_end(data) -> int:
    """Where the CDR of a DisciplineInfo or IterationRecord ends in ``data``: before the zero
    padding (0-3 bytes) DDS may add. The last field, the signature string, starts 4-aligned in
    the payload and holds 0 or 64 characters plus its NUL, so the message is 1 byte past a multiple
    of 4 long (counting the 4-byte encapsulation)."""
    return len(data) - (len(data) - 1) % 4


def _tail_signed(data) -> tuple | None:
    """The parts of the CDR bytes of a DisciplineInfo or IterationRecord (``signature`` is their
    last field) that its signature covers: the bytes with that field blank. None when the last field
    is not a signature of 64 ASCII characters."""
    end = _tail_end(data)
    at = end - len(BLANK_SIGNATURE) - SIGNATURE_CHARS
    if at < 4 or any(memoryview(data)[end:]):
        return None
    return signed_bytes(data, at, end)


def _rclpy_cdr(msg) -> bytes:
    """CDR bytes of a generated message, by rclpy's own serializer (its one codec)."""
    from rclpy.serialization import serialize_message

    return serialize_message(msg)


class Signer:
    """Signs outgoing and verifies incoming requests and results with one shared key."""

    def __init__(self, key: bytes, window_s: float = 30.0, clock_ns: Callable[[], int] = time.time_ns,
                 max_seen: int = 1_000_000):
        if len(key) < MIN_KEY_BYTES:
            raise AuthError(f"key shorter than {MIN_KEY_BYTES} bytes")
        self._hmac = hmac.new(key, digestmod="sha256")
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

    def _mac(self, *parts) -> str:
        h = self._hmac.copy()  # the key's inner and outer pads are hashed once, in __init__
        for p in parts:
            h.update(p)
        return h.hexdigest()

    # -- signing: the bytes that are sent, encoded once ---------------------------------------
    def sign_request(self, msg) -> bytes:
        """Sign an EvaluationRequest: returns its CDR bytes to publish (``msg.signature`` is set)."""
        return encode_request(msg, self._mac)

    def sign_result(self, msg) -> bytes:
        """Sign an EvaluationResult: returns its CDR bytes to publish (``msg.signature`` is set)."""
        return encode_result(msg, self._mac)

    def sign_info(self, msg) -> bytes:
        """Sign a DisciplineInfo: returns its CDR bytes to publish (``msg.signature`` is set)."""
        return self._sign_typed(msg)

    def sign_iteration(self, msg) -> bytes:
        """Sign an IterationRecord: returns its CDR bytes to publish (``msg.signature`` is set)."""
        return self._sign_typed(msg)

    def _sign_typed(self, msg) -> bytes:
        # rclpy's serializer leaves CDR padding bytes as it finds them, so a message serialised
        # twice need not give the same bytes: the bytes signed are the bytes to publish
        msg.signature = ""
        out = bytearray(_rclpy_cdr(msg))
        return signed(out, len(out) - len(BLANK_SIGNATURE), msg, self._mac)

    # -- verifying: the bytes that were received, with the signature field blanked -------------
    def verify_info(self, data) -> str | None:
        """None if the declaration (its received CDR bytes) is authentic, else "unsigned" or
        "forged". No freshness window: declarations are TRANSIENT_LOCAL, a late coordinator gets
        old ones, and a replayed genuine declaration says nothing new."""
        return self._mac_only(data)

    def verify_iteration(self, data) -> str | None:
        """None if the iteration record (its CDR bytes, received or read from a bag) is authentic,
        else "unsigned" or "forged" (no freshness window: also offline)."""
        return self._mac_only(data)

    def sign_declaration(self, text: str) -> str:
        """Signature of a recorder's declaration (its JSON text; recorder_node.OwnRecorder)."""
        return self._mac(b"recorder declaration\0", text.encode())

    def verify_declaration(self, text: str, signature: str) -> str | None:
        """None if a recorder's declaration is authentic, else "unsigned" or "forged" (MAC only,
        as for a discipline's declaration)."""
        if not signature:
            return "unsigned"
        return None if hmac.compare_digest(str(signature), self.sign_declaration(text)) else "forged"

    def _mac_only(self, data) -> str | None:
        parts = _tail_signed(data)
        end = _tail_end(data)
        if parts is None:
            return "unsigned" if bytes(data[end - len(BLANK_SIGNATURE):end]) == BLANK_SIGNATURE else "forged"
        sig = bytes(data[end - SIGNATURE_CHARS - 1:end - 1])
        return None if hmac.compare_digest(sig, self._mac(*parts).encode()) else "forged"

    def verify_request(self, msg) -> str | None:
        """None if the request is authentic and fresh, else the reason (one of REASONS). ``msg`` as
        decoded by wire.decode_request (its received bytes are checked) or a message object (its
        fields are encoded by the one codec, wire.py)."""
        return self._verify(msg, unsigned_request, ("req", msg.run_id, int(msg.evaluation_id), msg.discipline))

    def verify_result(self, msg) -> str | None:
        """None if the result is authentic and fresh, else the reason (one of REASONS); ``msg`` as
        for verify_request."""
        return self._verify(msg, unsigned_result, ("res", msg.run_id, int(msg.evaluation_id), msg.discipline))

    def _verify(self, msg, unsigned: Callable, ids: tuple) -> str | None:
        sig = msg.signature
        if not sig:
            return "unsigned"
        if len(sig) != SIGNATURE_CHARS or not sig.isascii():
            return "forged"
        raw = getattr(msg, "raw", None)
        if raw is not None:  # as received: MAC those bytes with the signature field blanked
            parts = signed_bytes(raw, msg.sig_at, msg.end)
            if parts is None or not hmac.compare_digest(sig, self._mac(*parts)):
                return "forged"
        elif not hmac.compare_digest(sig, self._mac(unsigned(msg))):
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
