"""A --bag folder that another run wrote into without leaving a bag (stopped before its recorder started, or
`--no-record --bag DIR` over ROS) holds that run's logs/: a second run into it was taken, and its node logs went
beside the first run's (appended to files of the same name), read as its own. A bag there is refused; so are
another run's logs and end-of-run record now, with the same one line, before anything is written."""
from __future__ import annotations

from pathlib import Path

import pytest

from bev_mdo.cli import main

LEAF = str(Path(__file__).resolve().parents[2] / "config" / "leaf_nedc.yaml")


def _left(folder: Path, name: str) -> dict:
    if name == "logs":  # as a run over ROS stopped before its recorder started leaves them
        (folder / "logs" / "ros").mkdir(parents=True)
        (folder / "logs" / "config.yaml").write_text("name: first\n")
        (folder / "logs" / "ros" / "python_1_1.log").write_text("[INFO] first run\n")
    else:
        folder.mkdir(parents=True)
        (folder / name).write_text("{}\n")
    return {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()}


@pytest.mark.parametrize("left", ["logs", "answers.json"])
@pytest.mark.parametrize("argv", [["--transport", "inprocess"], ["--transport", "ros", "--no-record"]],
                         ids=["inprocess", "ros-no-record"])
def test_a_bag_folder_holding_another_runs_files_is_refused_in_one_line(tmp_path, capsys, left, argv):
    bag = tmp_path / "b"
    before = _left(bag, left)
    assert main(["optimize", LEAF, "--bag", str(bag), "--quiet", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    said = "logs/" if left == "logs" else left
    assert err == [f"bev-mdo optimize: error: --bag {bag}: holds another run's {said}; choose a new directory"]
    assert {p: p.read_bytes() for p in bag.rglob("*") if p.is_file()} == before  # nothing written, nothing removed


def test_an_empty_folder_is_taken(tmp_path, capsys):
    bag = tmp_path / "b"
    (bag / "logs").mkdir(parents=True)  # made by hand, empty
    assert main(["optimize", LEAF, "--bag", str(bag), "--quiet", "--transport", "inprocess"]) == 0
    assert (bag / "b_0.mcap").is_file()
