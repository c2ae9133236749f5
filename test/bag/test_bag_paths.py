"""Every command that reads a bag takes the same three paths (bev_mdo.bag.reader.find_mcap): the bag
directory, its .mcap file, and a run's output folder holding exactly one bag (pareto's and sweep's
--out: ``bag/``). A folder holding several bags, or none, is a one-line error naming them."""
from __future__ import annotations

import contextlib
import io
import shutil

import pytest

from bev_mdo.cli import main

from .conftest import write_synthetic

READERS = [["bag", "info"], ["bag", "repair"], ["history"], ["report"]]
EVERY = READERS + [["resume", "--transport", "inprocess"], ["replay"]]


def _run(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(argv)
    return rc, out.getvalue(), err.getvalue()


@pytest.fixture
def out_folder(tmp_path):
    """A run's output folder: front.csv beside bag/ (what pareto --out writes)."""
    write_synthetic(tmp_path / "out" / "bag", n_iterations=6)
    (tmp_path / "out" / "front.csv").write_text("x\n1\n")
    return tmp_path / "out"


@pytest.mark.parametrize("cmd", READERS, ids=" ".join)
@pytest.mark.parametrize("which", ["folder", "mcap", "output folder"])
def test_a_bag_by_its_folder_its_mcap_file_or_the_run_output_folder(cmd, which, out_folder):
    """bag info, bag repair and resume refused a run's output folder (only history and report had
    their own look for the bag inside)."""
    path = {"folder": out_folder / "bag", "mcap": out_folder / "bag" / "bag_0.mcap",
            "output folder": out_folder}[which]
    rc, out, err = _run(cmd + [str(path)])
    assert rc == 0, err
    assert "Traceback" not in err and out


@pytest.mark.parametrize("cmd", EVERY, ids=lambda c: " ".join(c[:2]))
def test_a_folder_of_several_bags_or_none_is_one_line(cmd, out_folder):
    shutil.copytree(out_folder / "bag", out_folder / "bag2")
    rc, out, err = _run(cmd + [str(out_folder)])
    assert rc == 2 and err.count("\n") == 1, err
    assert "holds no .mcap file but 2 bags (bag, bag2): name one" in err
    shutil.rmtree(out_folder / "bag")
    shutil.rmtree(out_folder / "bag2")
    rc, out, err = _run(cmd + [str(out_folder)])
    assert rc == 2 and err.count("\n") == 1 and "holds no .mcap file" in err, err


@pytest.mark.parametrize("cmd", [c for c in EVERY if c != ["replay"]], ids=lambda c: " ".join(c[:2]))
def test_a_device_that_is_not_a_bag_is_one_line(cmd):
    """/dev/null (neither a file nor a folder) gave exit 7, 'NotADirectoryError ... (raised at pathlib.py)'."""
    rc, _, err = _run(cmd + ["/dev/null"])
    assert rc == 2 and err.strip().splitlines() == [err.strip()] and "/dev/null: empty file, not an MCAP bag" in err
