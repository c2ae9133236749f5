"""A bag's signing state, in the bag's own metadata and under the run's key.

Every bag written with a run's configuration holds the MCAP metadata record ``bev_mdo_signing``:
``signed`` ("true"/"false"), ``run_id`` and, for a signed run, ``key_fingerprint`` (a hash of
the key, never the key), ``config_sha256`` (of the stored configuration text) and ``signature``
(HMAC-SHA256 with the run's key over the other fields). A reader (``verifier``) checks the bag
against it before it trusts a record, with a key from OUTSIDE the bag: the one the user gives
(``--key-file``), else the run's key where bev-mdo keeps it (``run_key_path``:
``<bag's parent>/.keys/<bag name>/sign.key``, the per-run key itself or a link to a configured
``ros.sign_key_file``, made when the bag is created: ``keep_run_key``). The key path in the bag's
stored configuration is never used to find the key: whoever can write the bag can write that path.
A signed bag without such a key, a bag that disagrees with its key (another fingerprint, an edited
signing record or configuration), and a run's bag with a key but no signing record or one saying
"not signed", are refused (BagError, one line) unless the user turns verification off explicitly
(``--no-verify``), and the output then says so.
"""
from __future__ import annotations

import hashlib
import hmac
import json
import os
import re
from dataclasses import dataclass
from pathlib import Path

from bev_mdo.bag.errors import BagError
from bev_mdo.yamlload import load_yaml

SIGNING_METADATA = "bev_mdo_signing"
NO_VERIFY_NOTE = "verification OFF (--no-verify): records are read without checking their signatures"


def key_fingerprint(key: bytes) -> str:
    """A short public name of a key (SHA-256 of a prefix and the key; the key cannot be recovered)."""
    return hashlib.sha256(b"bev_mdo key fingerprint\0" + key).hexdigest()[:32]


def config_key_file(config_yaml: str) -> str:
    """``ros.sign_key_file`` named in the configuration a bag is written with ('' when none or unreadable)."""
    try:
        return named_key_file(load_yaml(config_yaml or ""))
    except ValueError:
        return ""


def named_key_file(config) -> str:
    """``ros.sign_key_file`` named in a parsed configuration (a bag's: ``Bag.stored_config.data``; '' when none)."""
    ros = config.get("ros") if isinstance(config, dict) else None
    value = ros.get("sign_key_file") if isinstance(ros, dict) else None
    return value if isinstance(value, str) else ""


def run_key_path(bag_dir) -> Path:
    """Where the key of the run recorded in ``bag_dir`` is kept: ``<bag's parent>/.keys/<bag name>/sign.key``,
    beside the bag directory, never in it (sessions.key_dir_for, protocol.signing.with_run_key)."""
    d = Path(os.path.abspath(bag_dir))
    return d.parent / ".keys" / d.name / "sign.key"


def keep_run_key(bag_dir, config_yaml: str) -> None:
    """Leave the run's key where readers look for it (``run_key_path``), as a new bag is created: for a run
    signed with a configured key elsewhere, a link to that file; for an unsigned run, no stale key of an
    earlier bag of the same name (it would make the readers refuse this one). The per-run key is there
    already. Best effort: a reader without it needs --key-file."""
    place = run_key_path(bag_dir)
    key_file = config_key_file(config_yaml)
    try:
        if not key_file:
            if place.is_symlink() or place.is_file():
                place.unlink()
            return
        target = Path(key_file).resolve()
        if place.resolve() == target:
            return
        place.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
        tmp = place.with_name(f".sign.key.{os.getpid()}")
        if tmp.is_symlink() or tmp.exists():
            tmp.unlink()
        os.symlink(target, tmp)
        os.replace(tmp, place)
    except OSError:
        pass


def _damaged_fingerprint(record: dict, key: bytes, whose: str) -> str:
    """'' or why a signing record whose ``key_fingerprint`` is not `key`'s is damaged, not of another key: the rest
    of it verifies with `key` (one byte of the fingerprint changed), or the fingerprint is no fingerprint at all."""
    said = record.get("key_fingerprint")
    mended = {**record, "key_fingerprint": key_fingerprint(key)}
    if hmac.compare_digest(str(record.get("signature", "")), _body_mac(key, mended)):
        return f"its key_fingerprint reads {said!r}, though the rest of it verifies with {whose}"
    if not (isinstance(said, str) and re.fullmatch(r"[0-9a-f]{32}", said)):
        return (f"its key_fingerprint {said!r} is not a key fingerprint (32 hex digits), so no key can be checked "
                "against it")
    return ""


def _body_mac(key: bytes, body: dict) -> str:
    text = json.dumps({k: v for k, v in body.items() if k != "signature"}, sort_keys=True)
    return hmac.new(key, text.encode("utf-8"), "sha256").hexdigest()


def state(config_yaml: str, run_id: str) -> dict[str, str]:
    """The ``bev_mdo_signing`` record for a bag of run `run_id` with `config_yaml` stored in it
    (the key is read from the file the configuration names; AuthError when it cannot be)."""
    from bev_mdo.protocol.signing import read_key  # the protocol's message store: loaded when a key is used

    key_file = config_key_file(config_yaml)
    if not key_file:
        return {"signed": "false", "run_id": run_id}
    key = read_key(key_file)
    body = {"signed": "true", "run_id": run_id, "key_fingerprint": key_fingerprint(key),
            "config_sha256": hashlib.sha256(config_yaml.encode("utf-8")).hexdigest()}
    body["signature"] = _body_mac(key, body)
    return body


@dataclass
class Verifier:
    """How a bag's records are checked: ``signer`` (None: not verified), ``note`` (one line the
    reader prints, '' when records are verified), ``signed`` (the run was signed)."""

    signer: object | None
    note: str
    signed: bool


def _found_key(bag, key_file: str | None) -> tuple[str, str]:
    """(path of the key to verify with, where it comes from) from outside the bag: `key_file` (--key-file),
    else the run's key at ``run_key_path`` when there is one; ('', '') when neither."""
    if key_file:
        return key_file, f"key file {key_file}"
    place = run_key_path(bag.bag_dir)
    if place.is_symlink() or place.exists():
        return str(place), f"key file {place} (the run's key beside the bag)"
    return "", ""


def verifier(bag, key_file: str | None = None, no_verify: bool = False) -> Verifier:
    """The Verifier for a bag (``bag.reader.Bag``), or BagError when the bag's signing record, its stored
    configuration and the key from outside the bag (``key_file``, else ``run_key_path``) disagree."""
    from bev_mdo.protocol.signing import AuthError, Signer, read_key

    where = bag.mcap_path
    record = bag.metadata.get(SIGNING_METADATA)
    config_yaml = bag.stored_config.text
    stored_key_file = named_key_file(bag.stored_config.data)
    if no_verify:
        return Verifier(None, NO_VERIFY_NOTE, bool(record and record.get("signed") == "true"))
    signed = record.get("signed") == "true" if record else bool(stored_key_file)
    given = bool(key_file)
    key_file, whose = _found_key(bag, key_file)
    if not key_file:
        if record and not signed and stored_key_file:
            raise BagError(f"{where}: the bag's signing record says the run was not signed, but its stored config "
                           f"names ros.sign_key_file {stored_key_file!r} (was the bag edited?); refusing it "
                           "(--no-verify reads it unverified)")
        if not signed:
            why = "its signing record says so" if record else "it has no signing record and its config names no key"
            return Verifier(None, f"records are not signed ({why}); they are read unverified", False)
        fingerprint = record.get("key_fingerprint", "?") if record else "?"
        if not stored_key_file:
            raise BagError(f"{where}: the bag's signing record says its records were signed (key {fingerprint}), but "
                           "its stored config names no ros.sign_key_file (was the bag edited?) and there is no run key at "
                           f"{run_key_path(bag.bag_dir)}; give the key with --key-file, or --no-verify to read it unverified")
        raise BagError(f"{where}: its records are signed (key {fingerprint}) and no key to verify them was given or "
                       f"found (no --key-file, no run key at {run_key_path(bag.bag_dir)}); the bag names "
                       f"{stored_key_file!r}, which is not trusted on the bag's word: give the key with --key-file, "
                       "or --no-verify to read it unverified")
    try:
        key = read_key(key_file, "--key-file" if given else "the run's key")
    except AuthError as exc:
        hint = "give another with --key-file, or" if given else "give the key with --key-file, or"
        raise BagError(f"{where}: cannot verify the iteration records: {exc} ({hint} --no-verify to read it "
                       "unverified)") from None
    if not record:
        if config_yaml:  # a run's bag: its writer stored its signing state beside its config
            raise BagError(f"{where}: the bag has no signing record (was it removed?), though {whose} should "
                           "verify it; refusing it (--no-verify reads it unverified)")
        return Verifier(Signer(key), "", True)  # a standalone recording: no config, each record is verified
    if not signed:
        raise BagError(f"{where}: the bag's signing record says the run was not signed, though {whose} should "
                       "verify it (was the bag edited?); refusing it (--no-verify reads it unverified)")
    if record.get("key_fingerprint") != key_fingerprint(key):
        if damaged := _damaged_fingerprint(record, key, whose):
            raise BagError(f"{where}: the bag's signing record is damaged: {damaged}; refusing it (--no-verify reads "
                           "it unverified)")
        raise BagError(f"{where}: {whose} is not the key this run was signed with (fingerprint "
                       f"{key_fingerprint(key)}, the bag's signing record says {record.get('key_fingerprint')})")
    if not hmac.compare_digest(record.get("signature", ""), _body_mac(key, record)):
        raise BagError(f"{where}: the bag's signing record does not verify with its key (edited?); refusing it")
    if record.get("config_sha256") != hashlib.sha256(config_yaml.encode("utf-8")).hexdigest():
        raise BagError(f"{where}: the stored config is not the one recorded with the run (edited after "
                       "recording?); refusing it")
    if record.get("run_id", "") != bag.info.get("run_id", record.get("run_id", "")):
        raise BagError(f"{where}: the bag's run id {bag.info.get('run_id')!r} is not the signed one "
                       f"{record.get('run_id')!r}; refusing it")
    return Verifier(Signer(key), "", True)
