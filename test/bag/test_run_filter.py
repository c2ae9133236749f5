"""history/resume read only the bag's own run and verify its signed iteration records."""
from __future__ import annotations

import secrets

import pytest
import yaml


from bev_mdo.bag.errors import BagError  # noqa: E402
from bev_mdo.bag.history import history, last_iterate  # noqa: E402
from bev_mdo.bag.reader import open_bag  # noqa: E402
from bev_mdo.bag.writer import BagWriter  # noqa: E402
from bev_mdo.protocol.signing import Signer, new_key_file, read_key  # noqa: E402


def _record(run_id, i, motor_kw):
    from bev_mdo_msgs.msg import IterationRecord, NamedArray

    rec = IterationRecord(run_id=run_id, sequence=i, iteration=i, formulation="mdf", optimizer="SLSQP",
                          objective_name="energy_wh_per_km", objective=100.0 - i, feasible=True)
    rec.header.stamp.sec = 1_700_000_000 + i
    rec.design = NamedArray(names=["motor_kw"], batch_size=1, values=[motor_kw])
    return rec


def _bag(tmp_path, name, own_run, records, key_file=""):
    from rclpy.serialization import serialize_message

    config = yaml.safe_dump({"name": "x", "ros": {"sign_key_file": key_file}})
    meta = {"config_yaml": config, **({"run_id": own_run} if own_run else {})}
    with BagWriter(tmp_path / name, metadata=meta) as w:
        w.add_topic("/bev_mdo/iteration", "bev_mdo_msgs/msg/IterationRecord")
        for t, rec in enumerate(records):
            data = rec if isinstance(rec, bytes) else serialize_message(rec)  # signed: the bytes the signer gave
            w.write("/bev_mdo/iteration", data, 1_700_000_000_000_000_000 + t)
    return tmp_path / name


def test_a_bag_of_several_runs_gives_its_own_run_verified(tmp_path):
    key_file = new_key_file(tmp_path / "keys")
    signer = Signer(read_key(key_file))
    recs = []
    for i in range(4):
        own = _record("mine", i, 80.0 + i)
        recs.append(signer.sign_iteration(own))                  # signed: the bytes to publish
        recs.append(_record("theirs", i, 60.0))                 # a concurrent run's record
        forged = _record("mine", 100 + i, 120.0)                 # forged under our id: unsigned ...
        recs.append(forged)
        bad = _record("mine", 200 + i, 120.0)
        recs.append(Signer(secrets.token_bytes(32)).sign_iteration(bad))  # ... or signed with another key
    from rclpy.serialization import deserialize_message
    from bev_mdo_msgs.msg import IterationRecord

    tampered = deserialize_message(signer.sign_iteration(_record("mine", 5, 80.0)), IterationRecord)
    tampered.design.values = [120.0]                             # a genuine record, changed afterwards
    recs.append(tampered)
    bag = _bag(tmp_path, "several", "mine", recs, key_file)
    checks: dict = {}
    rows = history(bag, checks=checks)
    assert [r["design"]["motor_kw"] for r in rows] == [80.0, 81.0, 82.0, 83.0]
    assert checks["dropped"] == {"unsigned": 4, "forged": 5} and checks["other_runs"] == 4
    _, design, iteration = last_iterate(bag)
    assert design == {"motor_kw": 83.0} and iteration == 3
    # without the key the run cannot be verified: history and resume refuse, unless told not to verify
    (tmp_path / "keys" / "sign.key").unlink()
    for read in (history, last_iterate):
        with pytest.raises(BagError, match="cannot verify the iteration records.*--no-verify"):
            read(bag)
    checks = {}
    assert history(bag, checks=checks, no_verify=True) and "verification OFF" in checks["unverified"]


def test_a_standalone_recording_of_several_runs_needs_a_run_id(tmp_path):
    bag = _bag(tmp_path, "standalone", None, [_record("a", 0, 80.0), _record("b", 0, 90.0)])
    with pytest.raises(BagError, match=r"2 runs \['a', 'b'\]; choose one with --run-id"):
        history(bag)
    assert [r["design"]["motor_kw"] for r in history(bag, "b")] == [90.0]
    assert len(history(bag, all_runs=True)) == 2
    assert open_bag(bag).info.get("run_id") is None


def test_report_reads_one_run_of_a_standalone_recording(tmp_path):
    from bev_mdo.bag.report import report

    bag = _bag(tmp_path, "standalone", None, [_record("a", 0, 80.0), _record("b", 0, 90.0), _record("b", 1, 91.0)])
    with pytest.raises(BagError, match="choose one with --run-id"):
        report(bag, tmp_path / "out")
    checks: dict = {}
    written = report(bag, tmp_path / "out", run_id="b", checks=checks)
    assert (tmp_path / "out" / "report.md") in written and checks["other_runs"] == 1
    md = (tmp_path / "out" / "report.md").read_text()
    assert "- run id: `b`," in md  # was: "run id: ``"
    # a recording apart from the run (bev-mdo record) holds no end-of-run record: how the run ended is not known
    # from it (it said "the run did not finish" of a run that had, and headed its iterate so)
    assert ("or the bag was recorded apart from it (`bev-mdo record`) or copied without its answers.json; what follows "
            "is its last recorded iterate") in md, md
    assert "## Last recorded iterate (how the run ended is not known)" in md
    # without --output-dir, each run's report in its own folder: the second no longer overwrote the first
    for run in ("a", "b"):
        assert bag / f"report_{run}" / "report.md" in report(bag, run_id=run)
        assert f"- run id: `{run}`," in (bag / f"report_{run}" / "report.md").read_text()
    # the review: '../../escape' wrote standalone/escape/report.md; a run the bag does not hold: nothing written
    assert report(bag, run_id="../../escape") == [] and sorted(p.name for p in bag.iterdir()) == [
        "metadata.yaml", "report_a", "report_b", "standalone_0.mcap"]


def test_history_and_resume_of_a_run_the_bag_does_not_hold_name_the_runs_it_holds(tmp_path, capsys):
    """history's line ended mid-sentence ('it holds 2 messages of '), then pointed at `bag info`, which does
    not list runs; resume said 'no IterationRecord on /bev_mdo/iteration', as if the bag held none."""
    from bev_mdo.cli import main

    bag = _bag(tmp_path, "standalone", None, [_record("a", 0, 80.0), _record("b", 0, 90.0), _record("a", 1, 81.0)])
    assert main(["history", str(bag), "--run-id", "deadbeef"]) == 1
    assert ("no iteration records of run deadbeef; it holds the iteration records of runs a, b"
            in capsys.readouterr().err)
    assert main(["resume", str(bag), "--run-id", "deadbeef", "--transport", "inprocess", "--no-record"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("bev-mdo resume: error: "), err
    assert "no record of run deadbeef; it holds the iteration records of runs a, b; choose one with --run-id" in err
    # the bag's own run when none is given: said to be the bag's own
    own = _bag(tmp_path, "own", "mine", [_record("theirs", 0, 80.0)])
    with pytest.raises(BagError, match=r"no record of run mine \(the bag's own\); it holds the iteration records "
                                       r"of run theirs; choose one with --run-id"):
        last_iterate(own)


def test_a_key_file_that_cannot_be_read_is_named_by_the_flag_the_user_typed(tmp_path, capsys):
    """A missing --key-file was reported as "ros.sign_key_file '...'", a config key the user did not write."""
    from bev_mdo.cli import main

    key_file = new_key_file(tmp_path / "keys")
    bag = _bag(tmp_path, "signed", "mine", [Signer(read_key(key_file)).sign_iteration(_record("mine", 0, 80.0))],
               key_file)
    short = tmp_path / "short.key"
    short.write_text("0123")
    short.chmod(0o600)  # a key file others may read is refused before its length is looked at
    for given, why in ((tmp_path / "missing.key", "cannot read (No such file or directory)"),
                       (short, "key shorter than 16 bytes")):
        for argv in (["history", str(bag)], ["report", str(bag)],
                     ["resume", str(bag), "--transport", "inprocess", "--no-record"]):
            assert main([*argv, "--key-file", str(given)]) == 2
            err = capsys.readouterr().err
            assert f"--key-file {str(given)!r}: {why} (give another with --key-file, or --no-verify" in err, err
            assert "ros.sign_key_file" not in err and err.count("\n") == 1, err
