"""The key that verifies a bag comes from outside the bag: --key-file, or the run's key beside the bag
(``<bag's parent>/.keys/<bag name>/sign.key``). Whoever can write the bag directory cannot make the readers
accept a change by pointing the bag at a key of their own, nor by stripping its signatures."""
from __future__ import annotations

import shutil

import pytest

from bev_mdo.bag.errors import BagError
from bev_mdo.bag.history import history
from bev_mdo.bag.reader import open_bag
from bev_mdo.bag.signing import SIGNING_METADATA, run_key_path, state
from bev_mdo.bag.writer import BagWriter
from bev_mdo.cli import main
from bev_mdo.protocol.messages import encode
from bev_mdo.protocol.signing import Signer, new_key_file, read_key
from test_fresh_records import RUN, TOPIC, _bag, _config, _record


def _forged(dst, config_yaml: str, records: list[bytes], signing: dict | None) -> None:
    """A bag written by hand into `dst` (what someone who can write the bag directory can do): bev_mdo
    metadata with `config_yaml`, the signing record `signing` (None: none), the config attachment, records."""
    from mcap.writer import Writer

    from bev_mdo.bag.schema import full_definition

    dst.mkdir(parents=True)
    with open(dst / f"{dst.name}_0.mcap", "wb") as f:
        w = Writer(f)
        w.start(profile="ros2", library="forger")
        w.add_metadata("bev_mdo", {"version": "0.1.0", "run_id": RUN, "config_yaml": config_yaml})
        if signing is not None:
            w.add_metadata(SIGNING_METADATA, signing)
        w.add_attachment(0, 0, "config.yaml", "application/yaml", config_yaml.encode())
        name = "bev_mdo_msgs/msg/IterationRecord"
        schema = w.register_schema(name, "ros2msg", full_definition(name).encode())
        channel = w.register_channel(TOPIC, "cdr", schema, {})
        for t, data in enumerate(records):
            w.add_message(channel, 1_700_000_000_000_000_000 + t, data, 1_700_000_000_000_000_000 + t, t)
        w.finish()


def _unsigned(rec) -> bytes:
    rec.signature = ""
    return bytes(encode(rec))


def _cli(capsys, *argv) -> tuple[int, str, str]:
    status = main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


@pytest.fixture
def run_bag(tmp_path):
    """(bag dir, the run's key file beside it, the genuine records 1..4: motor_kw 80..83): a run as
    `optimize` leaves it, its per-run key in ``<parent>/.keys/<bag name>/sign.key``."""
    bag = tmp_path / "bags" / "run"
    key_file = new_key_file(tmp_path / "bags" / ".keys" / "run")
    signer = Signer(read_key(key_file))
    recs = [signer.sign_iteration(_record(RUN, s, 79.0 + s)) for s in range(1, 5)]
    _bag(bag, recs, _config(key_file))
    assert str(run_key_path(bag)) == key_file and len(history(bag)) == 4
    return bag, key_file, recs


def _refused_by_every_reader(capsys, tmp_path, bag, *extra) -> list[str]:
    errors = []
    for argv in (["history", str(bag)], ["report", str(bag), "--output-dir", str(tmp_path / "r")],
                 ["resume", str(bag), "--transport", "inprocess", "--no-record"],
                 ["replay", str(bag), "--no-wait", "--as-fast-as-possible"]):  # replay published it all, exit 0
        status, out, err = _cli(capsys, *argv, *extra)
        assert status == 2 and len(err.strip().splitlines()) == 1, (argv, status, err)
        assert not out.strip()
        errors.append(err)
    return errors


def test_a_bag_pointed_at_another_key_and_re_signed_is_refused(tmp_path, run_bag, capsys):
    bag, key_file, _ = run_bag
    evil = new_key_file(tmp_path / "evil")
    config_yaml = _config(evil)
    forger = Signer(read_key(evil))
    recs = [forger.sign_iteration(_record(RUN, s, 120.0 if s == 4 else 79.0 + s)) for s in range(1, 5)]
    shutil.rmtree(bag)  # rewritten in place: the run's key beside it stays
    _forged(bag, config_yaml, recs, state(config_yaml, RUN))
    with pytest.raises(BagError, match="is not the key this run was signed with"):
        history(bag)
    for err in _refused_by_every_reader(capsys, tmp_path, bag):
        assert "is not the key this run was signed with" in err
    # given with --key-file, the run's key refuses it as well
    for err in _refused_by_every_reader(capsys, tmp_path, bag, "--key-file", key_file):
        assert "is not the key this run was signed with" in err
    # moved away from its run's key, the key the bag names is not used on the bag's word
    moved = tmp_path / "elsewhere" / "run"
    shutil.copytree(bag, moved)
    for err in _refused_by_every_reader(capsys, tmp_path, moved):
        assert "not trusted on the bag's word" in err and "--key-file" in err


def test_a_bag_stripped_of_its_signatures_is_refused_when_its_run_has_a_key(tmp_path, run_bag, capsys):
    bag, key_file, _ = run_bag
    config_yaml = _config("").replace("sign_key_file: ''\n", "")
    recs = [_unsigned(_record(RUN, s, 120.0 if s == 4 else 79.0 + s)) for s in range(1, 5)]
    shutil.rmtree(bag)
    _forged(bag, config_yaml, recs, None)
    with pytest.raises(BagError, match="no signing record"):
        history(bag)
    for err in _refused_by_every_reader(capsys, tmp_path, bag):
        assert "no signing record" in err
    # a record that says "not signed" is refused the same way
    shutil.rmtree(bag)
    _forged(bag, config_yaml, recs, {"signed": "false", "run_id": RUN})
    for err in _refused_by_every_reader(capsys, tmp_path, bag):
        assert "says the run was not signed" in err
    # moved to another machine, with the run's key given: refused too
    moved = tmp_path / "elsewhere" / "run"
    shutil.copytree(bag, moved)
    for err in _refused_by_every_reader(capsys, tmp_path, moved, "--key-file", key_file):
        assert "says the run was not signed" in err


def test_a_bag_signed_with_a_configured_key_is_verified_beside_it_and_with_key_file_when_moved(tmp_path, capsys):
    team = new_key_file(tmp_path / "team")  # ros.sign_key_file in the user's own config
    signer = Signer(read_key(team))
    recs = [signer.sign_iteration(_record(RUN, s, 79.0 + s)) for s in range(1, 5)]
    bag = _bag(tmp_path / "bags" / "shared", recs, _config(team))
    place = run_key_path(bag)
    assert place.is_symlink() and place.resolve() == (tmp_path / "team" / "sign.key").resolve()
    assert len(history(bag)) == 4
    status, out, err = _cli(capsys, "history", str(bag), "--csv", "-")
    assert status == 0 and len(out.strip().splitlines()) == 5 and not err
    moved = tmp_path / "other_host" / "shared"
    shutil.copytree(bag, moved)
    with pytest.raises(BagError, match="not trusted on the bag's word"):
        history(moved)
    assert [r["sequence"] for r in history(moved, key_file=team)] == [1, 2, 3, 4]
    status, out, err = _cli(capsys, "history", str(moved), "--key-file", team, "--csv", "-")
    assert status == 0 and len(out.strip().splitlines()) == 5


def test_a_new_unsigned_bag_removes_a_stale_key_of_its_name(tmp_path):
    from rclpy.serialization import serialize_message

    stale = new_key_file(tmp_path / ".keys" / "plain")  # left by an earlier bag of that name, deleted since
    bag = _bag(tmp_path / "plain", [serialize_message(_record(RUN, s, 80.0)) for s in (1, 2)], _config(""))
    assert not run_key_path(bag).exists() and str(run_key_path(bag)) == stale
    checks: dict = {}
    assert len(history(bag, checks=checks)) == 2 and "not signed" in checks["unverified"]


def test_a_standalone_recording_is_verified_with_the_key_given(tmp_path, capsys):
    """`bev-mdo record --output X` stores no config and so no signing record: --key-file verifies its records."""
    key_file = new_key_file(tmp_path / "k")
    signer = Signer(read_key(key_file))
    forged = Signer(read_key(new_key_file(tmp_path / "evil"))).sign_iteration(_record(RUN, 5, 120.0))
    recs = [signer.sign_iteration(_record(RUN, s, 79.0 + s)) for s in range(1, 5)] + [forged]
    bag = tmp_path / "rec"
    with BagWriter(bag, metadata={"run_id": "", "recorder": "/recorder_node"}) as w:
        w.add_topic(TOPIC, "bev_mdo_msgs/msg/IterationRecord")
        for t, data in enumerate(recs):
            w.write(TOPIC, data, 1_700_000_000_000_000_000 + t)
    assert SIGNING_METADATA not in open_bag(bag).metadata
    checks: dict = {}
    rows = history(bag, RUN, key_file=key_file, checks=checks)
    assert [r["sequence"] for r in rows] == [1, 2, 3, 4] and checks["dropped"] == {"forged": 1}
    status, out, err = _cli(capsys, "history", str(bag), "--run-id", RUN, "--key-file", key_file, "--csv", "-")
    assert status == 0 and len(out.strip().splitlines()) == 5 and "dropped 1 forged" in err
    status, out, err = _cli(capsys, "history", str(bag), "--run-id", RUN)
    assert status == 2 and "give the key with --key-file" in err


def test_replay_refuses_a_run_with_a_forged_record_unless_no_verify(tmp_path, run_bag, capsys, ros_domain):
    """replay published every record of a bag whose history said 'dropped 1 forged iteration record(s)'."""
    bag, key_file, recs = run_bag
    forged = Signer(read_key(new_key_file(tmp_path / "evil"))).sign_iteration(_record(RUN, 5, 120.0))
    shutil.rmtree(bag)
    _bag(bag, recs + [forged], _config(key_file))
    status, out, err = _cli(capsys, "replay", str(bag), "--no-wait", "--as-fast-as-possible")
    assert status == 2 and not out and err.strip().splitlines() == [
        f"bev-mdo replay: error: {bag / 'run_0.mcap'}: 1 forged iteration record(s) (not signed with the run's key); "
        "refusing to replay it (--no-verify replays it as is)"]
    status, out, err = _cli(capsys, "replay", str(bag), "--no-wait", "--as-fast-as-possible", "--no-verify")
    assert status == 0 and out.startswith("replayed ") and "verification OFF (--no-verify)" in err


def test_replay_help_names_no_config_it_does_not_take(capsys):
    """replay's discovery help said its default was 'the config's ros: section'; replay takes no config."""
    with pytest.raises(SystemExit):
        main(["replay", "--help"])
    text = capsys.readouterr().out
    assert "ROS discovery (default: localhost only)" in text and "config" not in text


@pytest.mark.parametrize("damage,said", [
    (lambda r: {**r, "key_fingerprint": r["key_fingerprint"][:7] + "g" + r["key_fingerprint"][8:]},  # 'f' -> 'g'
     "though the rest of it verifies with key file"),
    (lambda r: {**r, "key_fingerprint": "not a fingerprint", "signature": "0" * 64},  # its signature damaged as well
     "is not a key fingerprint (32 hex digits)"),
], ids=["one_byte_flipped", "not_hex"])
def test_a_damaged_fingerprint_in_the_signing_record_is_said_to_be_damage(tmp_path, run_bag, capsys, damage, said):
    """One flipped byte in the signing record's key_fingerprint ('9ae1f59g...', no longer hex) blamed the run's key
    ("is not the key this run was signed with"): the record is damaged, and the readers say so."""
    bag, key_file, recs = run_bag
    config_yaml = _config(key_file)
    signing = state(config_yaml, RUN)
    shutil.rmtree(bag)
    _forged(bag, config_yaml, recs, damage(signing))
    with pytest.raises(BagError, match="the bag's signing record is damaged: its key_fingerprint") as info:
        history(bag)
    assert said in str(info.value) and "is not the key this run was signed with" not in str(info.value)
    for err in _refused_by_every_reader(capsys, tmp_path, bag):
        assert "signing record is damaged" in err and said in err


def test_report_md_says_a_forged_record_was_dropped(tmp_path, run_bag, capsys):
    """A ROS trial: report's stderr said 'dropped 1 forged iteration record(s)', and the report.md it wrote
    opened with 'the run finished' and said nothing of it."""
    bag, key_file, recs = run_bag
    forged = Signer(read_key(new_key_file(tmp_path / "evil"))).sign_iteration(_record(RUN, 5, 120.0))
    shutil.rmtree(bag)
    _bag(bag, recs + [forged], _config(key_file))
    status, out, err = _cli(capsys, "report", str(bag), "--output-dir", str(tmp_path / "r"))
    assert status == 0 and "dropped 1 forged iteration record(s)" in err, err
    assert "- **dropped 1 forged iteration record(s)" in (tmp_path / "r" / "report.md").read_text()
