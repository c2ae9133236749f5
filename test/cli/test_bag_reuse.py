"""A --bag folder that another run wrote into without leaving a bag (stopped before its recorder started, or
`--no-record --bag DIR` over ROS) holds that run's logs/: a second run into it was taken, and its node logs went
beside the first run's (appended to files of the same name), read as its own. A bag there is refused, and so is
another run's end-of-run record, with the same one line, before anything is written; logs/ alone are moved aside
(logs.1/, ...), said in one line, and the folder is reused: the same command runs again after a Ctrl-C."""
from __future__ import annotations

from pathlib import Path

import pytest

from bev_mdo.api.runbag import CLAIM_FILE
from bev_mdo.cli import main

LEAF = str(Path(__file__).resolve().parents[2] / "config" / "leaf_nedc.yaml")


def _left(folder: Path, name: str) -> dict:
    if name == "logs":  # as a run over ROS stopped before its recorder started leaves them
        (folder / "logs" / "ros").mkdir(parents=True)
        (folder / "logs" / "config.yaml").write_text("name: first\n")
        (folder / "logs" / "ros" / "python_1_1.log").write_text("[INFO] first run\n")
    else:
        folder.mkdir(parents=True, exist_ok=True)
        (folder / name).write_text("{}\n")
    return {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()}


@pytest.mark.parametrize("left", [["answers.json"], ["logs", "answers.json"]], ids=["answers", "logs+answers"])
@pytest.mark.parametrize("argv", [["--transport", "inprocess"], ["--transport", "ros", "--no-record"]],
                         ids=["inprocess", "ros-no-record"])
def test_a_bag_folder_holding_another_runs_files_is_refused_in_one_line(tmp_path, capsys, left, argv):
    bag = tmp_path / "b"
    before = {}
    for name in left:
        before.update(_left(bag, name))
    assert main(["optimize", LEAF, "--bag", str(bag), "--quiet", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    said = " and ".join(n + "/" * (n == "logs") for n in left)
    assert err == [f"bev-mdo optimize: error: --bag {bag}: holds another run's {said}; choose a new directory"]
    assert {p: p.read_bytes() for p in bag.rglob("*") if p.is_file()} == before  # nothing written, nothing removed


def test_the_logs_of_a_run_that_wrote_no_bag_are_moved_aside_and_the_folder_reused(tmp_path, capsys):
    """The folder a run stopped before its recorder started left (logs/, an unlocked claim file) was refused to the
    same command run again ('holds another run's logs/'), though the docs said it blocks nothing. Its logs go to
    logs.1/ (then logs.2/), untouched, said in one line, and the run writes its bag there."""
    bag = tmp_path / "b"
    before = _left(bag, "logs")
    (bag / ".bev_mdo_claim").write_text("")  # as a run killed with SIGKILL leaves it
    for n in (1, 2):
        assert main(["optimize", LEAF, "--bag", str(bag), "--quiet", "--transport", "inprocess"]) == 0
        err = capsys.readouterr().err.strip().splitlines()
        assert err == [f"--bag {bag}: the logs/ of an earlier run that wrote no bag moved to logs.{n}/"], err
        assert {p.relative_to(bag / f"logs.{n}"): b for p, b in _files(bag / f"logs.{n}").items()} == {
            p.relative_to(bag / "logs"): b for p, b in before.items()}
        assert (bag / "b_0.mcap").is_file() and not (bag / ".bev_mdo_claim").exists()
        for f in bag.glob("b_0.mcap"):  # the next round: the same leftover again, beside the first one moved
            f.unlink()
        (bag / "metadata.yaml").unlink()
        _left(bag, "logs")


def _files(folder: Path) -> dict:
    return {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()}


def test_an_empty_folder_is_taken(tmp_path, capsys):
    bag = tmp_path / "b"
    (bag / "logs").mkdir(parents=True)  # made by hand, empty
    assert main(["optimize", LEAF, "--bag", str(bag), "--quiet", "--transport", "inprocess"]) == 0
    assert (bag / "b_0.mcap").is_file()


def test_a_plain_file_named_logs_is_refused_as_what_it_is(tmp_path, capsys):
    bag = tmp_path / "b"
    bag.mkdir()
    (bag / "logs").write_text("my notes\n")
    assert main(["optimize", LEAF, "--bag", str(bag), "--quiet", "--transport", "inprocess"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"bev-mdo optimize: error: --bag {bag}: holds a file named logs (a run writes its logs/ there); "
                   "choose a new directory"]


def _holding(out: Path, what: str) -> dict:
    """`out` as an earlier run left it: its bag in the folder itself (optimize --bag OUT), or its logs/."""
    from bev_mdo.bag.writer import BagWriter

    if what == "bag":
        BagWriter(out, metadata={"run_id": "first"}).close()
        return {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    return _left(out, what)


OUT_COMMANDS = pytest.mark.parametrize("command", [  # the commands with an --out folder
    ["sweep", LEAF, "--vary", "motor_kw=70,90", "--no-plots", "--transport", "inprocess"],
    ["pareto", LEAF, "--objectives", "energy_wh_per_km,accel_time_0_100_s", "--generations", "1", "--pop", "4",
     "--transport", "inprocess"]], ids=["sweep", "pareto"])


@OUT_COMMANDS
@pytest.mark.parametrize("held, said", [("bag", "a bag already exists there"),
                                        ("answers.json", "holds another run's answers.json")])
def test_an_out_folder_holding_another_runs_bag_or_files_is_refused(tmp_path, capsys, command, held, said):
    """Only OUT/bag was checked: `sweep --out OUT` (`pareto --out OUT`) into an optimize run's bag folder was taken,
    and `resume OUT` then resumed the old optimize run. The line names the folder as given, not OUT/bag."""
    out = tmp_path / "out"
    before = _holding(out, held)
    assert main([*command, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"bev-mdo {command[0]}: error: --out {out}: {said}; choose a new directory"]
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before


@OUT_COMMANDS
def test_an_out_folder_holding_only_a_stopped_runs_logs_is_reused(tmp_path, capsys, command):
    out = tmp_path / "out"
    before = _left(out, "logs")
    assert main([*command, "--out", str(out)]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert f"--out {out}: the logs/ of an earlier run that wrote no bag moved to logs.1/" in err, err
    assert {p.relative_to(out / "logs.1"): b for p, b in _files(out / "logs.1").items()} == {
        p.relative_to(out / "logs"): b for p, b in before.items()}
    assert any((out / "bag").glob("*.mcap"))


@OUT_COMMANDS
def test_an_out_folder_of_a_finished_run_is_named_as_given(tmp_path, capsys, command):
    out = tmp_path / "out"
    from bev_mdo.bag.writer import BagWriter

    BagWriter(out / "bag", metadata={"run_id": "first"}).close()
    assert main([*command, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"bev-mdo {command[0]}: error: --out {out}: a run's output folder, its bag in bag/; choose a new "
                   "directory"]


def test_a_folder_of_several_runs_bags_is_not_called_a_runs_output_folder(tmp_path, capsys):
    """--bag bags/ (the folder every run's bag goes into) was refused as 'a run's output folder, its bag in
    <one of them>/', naming one run of many."""
    from bev_mdo.bag.writer import BagWriter

    for name in ("run_b", "run_a", "run_c", "run_d"):
        BagWriter(tmp_path / "bags" / name, metadata={"run_id": name}).close()
    assert main(["optimize", LEAF, "--transport", "inprocess", "--bag", str(tmp_path / "bags"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"--bag {tmp_path / 'bags'}: holds 4 runs' bags (run_a/, run_b/, run_c/, ...); choose a new directory" in err, err


def test_over_ros_the_rerun_keeps_its_node_logs_apart_from_the_stopped_runs(tmp_path, capsys, ros_domain):
    """The same over ROS, where the logs are written: the new run's logs/ holds its own config and logs alone."""
    bag = tmp_path / "b"
    before = _left(bag, "logs")
    assert main(["optimize", LEAF, "--bag", str(bag), "--quiet", "--domain-id", str(ros_domain)]) == 0
    assert f"--bag {bag}: the logs/ of an earlier run that wrote no bag moved to logs.1/" in capsys.readouterr().err
    assert _files(bag / "logs.1") == {bag / "logs.1" / p.relative_to(bag / "logs"): b for p, b in before.items()}
    assert (bag / "logs" / "config.yaml").read_text() != "name: first\n" and any(bag.glob("*.mcap"))
    assert not any(b"first run" in b for b in _files(bag / "logs").values())


def test_old_logs_that_cannot_be_moved_are_said_as_such(tmp_path, capsys, monkeypatch):
    """An OS error while moving the stopped run's logs/ aside was reported as 'cannot create the bag directory'."""
    bag = tmp_path / "b"
    before = _left(bag, "logs")

    def refuse(self, target):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(Path, "rename", refuse)
    assert main(["optimize", LEAF, "--transport", "inprocess", "--bag", str(bag), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"bev-mdo optimize: error: --bag {bag}: cannot move the logs/ of an earlier run that wrote no bag "
                   "to logs.1/ (Permission denied); move or remove it"], err
    assert _files(bag / "logs") == before and not (bag / CLAIM_FILE).exists() and not any(bag.glob("*.mcap"))
