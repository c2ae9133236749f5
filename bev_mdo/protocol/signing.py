"""Message authentication with a shared key: HMAC-SHA256 from the standard library.

The pip build of Fast DDS has no DDS-Security, so SROS2 cannot be enforced with it. With
``ros.sign_key_file`` set, every message bev_mdo signs carries ``signature = hex(HMAC-SHA256(key,
the message's CDR bytes with the signature field empty))``: the sender encodes once with the field
empty, MACs and puts the signature in (64 characters, so every later field keeps its alignment);
the receiver blanks the field in the bytes it received (``messages.field_offset``) and MACs those.
A request or result is dropped as ``unsigned``, ``forged``, ``expired`` (stamp further than
``window_s`` from the receiver's clock, either way) or ``replayed`` (a retry has ``attempt + 1`` and
a fresh stamp, so a new signature); declarations and iteration records are verified by MAC only.
The key is only ever read from the file. This module keeps the key, the Signer, the freshness and
replay window and the reasons; docs/security.md has the whole scheme.
"""
from __future__ import annotations

import hmac
import os
import time
from collections import OrderedDict
from pathlib import Path
from typing import Callable

from bev_mdo.protocol.messages import (DisciplineInfo, IterationRecord, WireError, decode, encode, field_offset,
                                       to_protocol)

MIN_KEY_BYTES = 16
SIGNATURE_CHARS = 64
BLANK_SIGNATURE = (1).to_bytes(4, "little") + b"\x00"  # a CDR string of length 0: u32 1, NUL
_SIGNED_LEN = (SIGNATURE_CHARS + 1).to_bytes(4, "little")
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


def read_key(path: str | os.PathLike, given_as: str = "ros.sign_key_file") -> bytes:
    """The shared key: the file's bytes without surrounding whitespace (>= 16 bytes). AuthError names the file
    as the user gave it, ``given_as`` (the config key, or a flag such as ``--key-file``); as ssh does with a
    private key, a file that group or others may read is refused (with the chmod that fixes it)."""
    p = Path(path)
    try:
        with open(p, "rb") as f:
            mode = os.fstat(f.fileno()).st_mode & 0o777
            key = f.read().strip()
    except OSError as exc:
        raise AuthError(f"{given_as} {str(p)!r}: cannot read ({exc.strerror})") from None
    if mode & 0o044:
        raise AuthError(f"{given_as} {str(p)!r}: mode {mode:04o} lets other users read the key; run: chmod 600 {p}")
    if len(key) < MIN_KEY_BYTES:
        raise AuthError(f"{given_as} {str(p)!r}: key shorter than {MIN_KEY_BYTES} bytes")
    return key


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


def signature_at(msg) -> int:
    """Where the signature field of a message starts in its CDR bytes (encapsulation included)."""
    return field_offset(msg, "signature")


def unsigned_bytes(msg) -> bytearray:
    """The bytes a signature of ``msg`` covers: its CDR with the signature field empty."""
    sig = msg.signature
    msg.signature = ""
    try:
        return encode(msg)
    finally:
        msg.signature = sig


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
        return self._sign(msg)

    def sign_result(self, msg) -> bytes:
        """Sign an EvaluationResult: returns its CDR bytes to publish (``msg.signature`` is set)."""
        return self._sign(msg)

    def sign_info(self, msg) -> bytes:
        """Sign a DisciplineInfo: returns its CDR bytes to publish (``msg.signature`` is set)."""
        return self._sign(msg)

    def sign_iteration(self, msg) -> bytes:
        """Sign an IterationRecord: returns its CDR bytes to publish (``msg.signature`` is set)."""
        return self._sign(msg)

    def _sign(self, msg) -> bytes:
        own = to_protocol(msg)  # a message of another codec (rclpy's classes) is read field by field
        own.signature = ""
        out = encode(own)
        at = signature_at(own)
        sig = self._mac(out)
        if out[at:at + len(BLANK_SIGNATURE)] != BLANK_SIGNATURE:
            raise ValueError("the signature field is not where the generated layout puts it")
        out[at:at + len(BLANK_SIGNATURE)] = _SIGNED_LEN + sig.encode("ascii") + b"\x00"
        msg.signature = own.signature = sig
        return bytes(out)

    # -- verifying: the bytes that were received, with the signature field blanked -------------
    def verify_info(self, data) -> str | None:
        """None if the declaration (its received CDR bytes) is authentic, else "unsigned" or
        "forged". No freshness window: declarations are TRANSIENT_LOCAL, a late coordinator gets
        old ones, and a replayed genuine declaration says nothing new."""
        return self._mac_only(data, DisciplineInfo)

    def verify_iteration(self, data) -> str | None:
        """None if the iteration record (its CDR bytes, received or read from a bag) is authentic,
        else "unsigned" or "forged" (no freshness window: also offline)."""
        return self._mac_only(data, IterationRecord)

    def sign_declaration(self, text: str) -> str:
        """Signature of a recorder's declaration (its JSON text; recorder_node.OwnRecorder)."""
        return self._mac(b"recorder declaration\0", text.encode())

    def sign_answers(self, text: str) -> str:
        """Signature of a run's end-of-run answers (their stored JSON text: api/runbag.finish), which name its result."""
        return self._mac(b"run answers\0", text.encode())

    def verify_answers(self, text: str, signature: str) -> str | None:
        """None if stored answers are the run's own, else "unsigned" or "forged"."""
        if not signature:
            return "unsigned"
        return None if hmac.compare_digest(str(signature), self.sign_answers(text)) else "forged"

    def verify_declaration(self, text: str, signature: str) -> str | None:
        """None if a recorder's declaration is authentic, else "unsigned" or "forged" (MAC only,
        as for a discipline's declaration)."""
        if not signature:
            return "unsigned"
        return None if hmac.compare_digest(str(signature), self.sign_declaration(text)) else "forged"

    def _mac_only(self, data, cls) -> str | None:
        try:
            msg = decode(data, cls)
        except WireError:
            return "forged"
        if any(memoryview(data)[msg.end:]):  # DDS pads with zeros only
            return "forged"
        return self._mac_check(msg)

    def _mac_check(self, msg) -> str | None:
        """None if the signature of a message verifies, else "unsigned" or "forged"."""
        sig = msg.signature
        if not sig:
            return "unsigned"
        if len(sig) != SIGNATURE_CHARS or not sig.isascii():
            return "forged"
        raw = getattr(msg, "raw", None)
        if raw is not None:  # as received: MAC those bytes with the signature field blanked
            parts = signed_bytes(raw, signature_at(msg), msg.end)
            if parts is None or not hmac.compare_digest(sig, self._mac(*parts)):
                return "forged"
        elif not hmac.compare_digest(sig, self._mac(unsigned_bytes(to_protocol(msg)))):
            return "forged"
        return None

    def verify_request(self, msg) -> str | None:
        """None if the request is authentic and fresh, else the reason (one of REASONS). ``msg`` as
        decoded by messages.decode (its received bytes are checked) or a message object (its
        fields are encoded by the generated codec)."""
        return self._verify(msg, ("req", msg.run_id, int(msg.evaluation_id), msg.discipline))

    def verify_result(self, msg) -> str | None:
        """None if the result is authentic and fresh, else the reason (one of REASONS); ``msg`` as
        for verify_request."""
        return self._verify(msg, ("res", msg.run_id, int(msg.evaluation_id), msg.discipline))

    def _verify(self, msg, ids: tuple) -> str | None:
        why = self._mac_check(msg)
        if why is not None:
            return why
        sig = msg.signature
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
