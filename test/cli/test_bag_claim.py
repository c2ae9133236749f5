"""Two runs given the same --bag at once: the check that no bag is there was separate from the creation of
the bag (check, then create), so both passed it. Over ROS the second then shared the first's key and logs
and its recorder failed on the first's bag, hidden in its log, while the run waited 60 s for it (exit 6).
The bag directory is now claimed where it is checked (api/runbag.claim_new_bag): the second run is
refused at once (the directory is being written by another run, not "a bag already exists there"), exit 2, and
writes nothing; a sweep's or pareto's --out is named as given, not its bag/. No ROS: the second run is started
from inside the first, at the point where the first holds its claim and nothing else."""
from __future__ import annotations

from pathlib import Path

import pytest

from bev_mdo.api.errors import InputError
from bev_mdo.bag.writer import BagWriter
from bev_mdo.cli import main

LEAF = str(Path(__file__).resolve().parents[2] / "config" / "leaf_nedc.yaml")


def test_a_claimed_bag_directory_is_refused_to_a_second_claim_until_released(tmp_path):
    from bev_mdo.api.runbag import CLAIM_FILE, claim_new_bag

    bag = tmp_path / "same" / "x"
    first = claim_new_bag(bag, "--bag")
    with pytest.raises(InputError, match=rf"^--bag {bag}: is being written by another run; choose a new directory$"):
        claim_new_bag(bag, "--bag")
    assert (bag / CLAIM_FILE).is_file()  # the refused claim left the holder's file alone
    first.release()
    assert not (tmp_path / "same").exists()  # nothing written: the folders the claim made are gone
    again = claim_new_bag(bag, "--bag")  # a run that ended without a bag does not block the next
    BagWriter(bag).close()
    again.release()
    assert sorted(p.name for p in bag.iterdir()) == ["metadata.yaml", "x_0.mcap"]  # no claim file left in the bag
    with pytest.raises(InputError, match="a bag already exists there"):
        claim_new_bag(bag, "--bag")


def test_a_claim_left_by_a_dead_process_does_not_block(tmp_path):
    """The lock goes with the process that held it (a run SIGKILLed before its bag existed)."""
    import subprocess
    import sys

    from bev_mdo.api.runbag import CLAIM_FILE, claim_new_bag

    bag = tmp_path / "x"
    code = f"from bev_mdo.api.runbag import claim_new_bag; c = claim_new_bag({str(bag)!r}, '--bag'); import os; os._exit(9)"
    assert subprocess.run([sys.executable, "-c", code], timeout=120).returncode == 9
    assert (bag / CLAIM_FILE).is_file()  # left behind, but no longer held
    claim_new_bag(bag, "--bag").release()


def _second_run_inside_the_first(monkeypatch, tmp_path, cls, method, argv):
    """Run `argv` (the second command) when the first reaches cls.method, then stop the first there."""
    seen = {}

    def second(*a, **k):
        if not seen:
            seen["status"] = None
            seen["status"] = main(argv)
            raise RuntimeError("the test stops the first run here")
        raise RuntimeError("the second run got as far as the first")

    monkeypatch.setattr(cls, method, second)
    return seen


def test_the_second_of_two_ros_runs_on_one_bag_is_refused_before_it_writes_anything(monkeypatch, tmp_path, capsys):
    """As reported: two `optimize --bag same/x` over ROS (the default) started together."""
    from bev_mdo.sessions import OptimizeRosSession

    bag = tmp_path / "same" / "x"
    argv = ["optimize", LEAF, "--bag", str(bag), "--domain-id", "196", "--quiet"]
    seen = _second_run_inside_the_first(monkeypatch, tmp_path, OptimizeRosSession, "__enter__", argv)
    main(argv)  # the first: claims the bag, then (patched) starts nothing
    err = capsys.readouterr().err
    assert seen["status"] == 2, err
    assert f"bev-mdo optimize: error: --bag {bag}: is being written by another run; choose a new directory" == \
        err.splitlines()[0], err
    assert "the second run got as far as the first" not in err
    assert not (tmp_path / "same" / ".keys").exists()  # neither the key nor the logs of the refused run
    assert not (bag / "logs").exists()


def test_the_second_of_two_in_process_runs_on_one_bag_is_refused(monkeypatch, tmp_path, capsys):
    from bev_mdo.api.runbag import InProcessBag

    bag = tmp_path / "x"
    argv = ["optimize", LEAF, "--transport", "inprocess", "--bag", str(bag), "--quiet"]
    seen = _second_run_inside_the_first(monkeypatch, tmp_path, InProcessBag, "__init__", argv)
    main(argv)
    err = capsys.readouterr().err
    assert seen["status"] == 2 and f"--bag {bag}: is being written by another run; choose a new directory" in err, err


def test_the_second_of_two_sweeps_into_one_out_folder_is_refused(monkeypatch, tmp_path, capsys):
    from bev_mdo.cli import sweep

    out = tmp_path / "sweep"
    argv = ["sweep", LEAF, "--vary", "motor_kw=70,90", "--out", str(out), "--no-plots", "--transport", "inprocess"]
    seen = _second_run_inside_the_first(monkeypatch, tmp_path, sweep, "evaluate_batch", argv)
    main(argv)
    err = capsys.readouterr().err
    assert seen["status"] == 2 and f"--out {out}: is being written by another run; choose a new directory" in err, err
    assert not out.exists()  # the first stopped before its bag: its claim's folders are gone too


def test_the_second_of_two_pareto_runs_into_one_out_folder_is_refused(monkeypatch, tmp_path, capsys):
    from bev_mdo import sessions

    out = tmp_path / "front"
    argv = ["pareto", LEAF, "--objectives", "energy_wh_per_km,accel_time_0_100_s", "--out", str(out), "--generations", "1",
            "--pop", "4", "--transport", "inprocess"]
    seen = _second_run_inside_the_first(monkeypatch, tmp_path, sessions.ParetoInProcessSession, "__init__", argv)
    main(argv)
    err = capsys.readouterr().err
    assert seen["status"] == 2 and f"error: --out {out}: is being written by another run; choose a new directory" \
        in err, err
