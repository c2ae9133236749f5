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


@pytest.fixture
def two_bags(tmp_path):
    """Two bags' files: a (6 iterations) and b (3), each in its own folder with its metadata.yaml."""
    write_synthetic(tmp_path / "a", n_iterations=6)
    write_synthetic(tmp_path / "b", n_iterations=3)
    return tmp_path / "a" / "a_0.mcap", tmp_path / "b" / "b_0.mcap"


@pytest.mark.parametrize("cmd", EVERY, ids=lambda c: " ".join(c[:2]))
def test_a_folder_of_two_mcap_files_is_refused_naming_them(cmd, two_bags, tmp_path):
    """A folder holding a_0.mcap and b_0.mcap (no metadata.yaml) was read as a_0.mcap, b_0.mcap ignored
    without a word; and so it was beside a metadata.yaml naming a third file."""
    d = tmp_path / "d"
    d.mkdir()
    for f in two_bags:
        shutil.copy(f, d)
    rc, out, err = _run(cmd + [str(d)])
    assert rc == 2 and err.count("\n") == 1, err
    assert f"{d}: holds 2 .mcap files (a_0.mcap, b_0.mcap): give the one to read" in err
    (d / "metadata.yaml").write_text((two_bags[0].parent / "metadata.yaml").read_text().replace("a_0.mcap", "c_0.mcap"))
    rc, out, err = _run(cmd + [str(d)])
    assert rc == 2 and err.count("\n") == 1, err
    if cmd == ["bag", "repair"]:  # it rewrites metadata.yaml, so it reads the folder's files, not the file named
        assert f"{d}: holds 2 .mcap files (a_0.mcap, b_0.mcap): give the one to read" in err
    else:
        assert (f"{d}: its metadata.yaml names c_0.mcap, not in the folder; it holds 2 .mcap files (a_0.mcap, "
                "b_0.mcap): give the .mcap file to read") in err
    if cmd in READERS:  # the file itself is read
        rc, out, err = _run(cmd + [str(d / "b_0.mcap")])
        assert rc == 0, err


def test_the_file_metadata_yaml_names_is_read(two_bags, tmp_path):
    """rosbag2's relative_file_paths names the bag's storage file: that one is read, whatever else lies beside it
    (a renamed bag folder's a_0.mcap, and a 0_0.mcap that sorts first)."""
    from bev_mdo.bag.reader import open_bag

    d = tmp_path / "renamed"
    shutil.copytree(two_bags[0].parent, d)
    shutil.copy(two_bags[1], d / "0_0.mcap")
    bag = open_bag(d)
    assert bag.mcap_path == d / "a_0.mcap" and bag.counts["/bev_mdo/iteration"] == 6


def test_repair_backups_are_not_storage_files(two_bags):
    """`bag repair` keeps the original as a_0.mcap.bak (then .bak1): the folder still reads as one bag, also
    without its metadata.yaml (a bag being written has none yet)."""
    d = two_bags[0].parent
    for _ in range(2):
        assert _run(["bag", "repair", "--force", str(d)])[0] == 0
    assert sorted(p.name for p in d.iterdir()) == ["a_0.mcap", "a_0.mcap.bak", "a_0.mcap.bak1", "metadata.yaml"]
    (d / "metadata.yaml").unlink()
    rc, out, err = _run(["history", str(d)])
    assert rc == 0 and "6 records" in out, err


def test_a_metadata_yaml_naming_another_file_is_refused_until_repair_rewrites_it(two_bags):
    """A bag folder whose metadata.yaml names a file not there was read as its one .mcap without a word;
    `bag repair` (which rewrites metadata.yaml) still takes that one file."""
    d = two_bags[0].parent
    (d / "a_0.mcap").rename(d / "x_0.mcap")
    rc, out, err = _run(["history", str(d)])
    assert rc == 2 and err.strip().splitlines() == [
        f"bev-mdo history: error: {d}: its metadata.yaml names a_0.mcap, not in the folder; it holds 1 .mcap file "
        "(x_0.mcap): give the .mcap file to read (or `bev-mdo bag repair` it: that rewrites metadata.yaml)"]
    assert _run(["bag", "repair", str(d)])[0] == 0
    rc, out, err = _run(["history", str(d)])
    assert rc == 0 and "6 records" in out, err


@pytest.mark.parametrize("cmd", [["bag", "info"], ["history"], ["report"]], ids=" ".join)
@pytest.mark.parametrize("text, why", [("rosbag2_bagfile_information: [unclosed\n", "is not valid YAML"),
                                       ("just text\n", "holds no rosbag2_bagfile_information mapping")])
def test_a_metadata_yaml_of_no_use_beside_a_good_mcap_is_said_to_be_ignored(cmd, text, why, tmp_path):
    """It was ignored without a word (the bag is read from its .mcap file all the same)."""
    bag = tmp_path / "run"
    write_synthetic(bag, n_iterations=3)
    (bag / "metadata.yaml").write_text(text)
    rc, out, err = _run([*cmd, str(bag)])
    assert rc == 0 and out, err
    said = [line for line in err.splitlines() if "metadata.yaml" in line]
    assert said == [f"{bag / 'metadata.yaml'} {why}: ignored, the bag is read from run_0.mcap (`bev-mdo bag "
                    "repair` writes it again)"], err


@pytest.mark.parametrize("cmd", [["history"], ["report"]], ids=" ".join)
@pytest.mark.parametrize("metadata", [None, "other_tool"])
def test_a_valid_mcap_without_a_bev_mdo_run_exits_2_saying_so(cmd, metadata, tmp_path):
    """report wrote a report of nothing and exited 0; history said 'no iteration records', exit 1."""
    from mcap.writer import Writer

    path = tmp_path / "other.mcap"
    with open(path, "wb") as f:
        writer = Writer(f)
        writer.start(profile="ros2", library="another tool")
        if metadata:
            writer.add_metadata(metadata, {"a": "b"})
        writer.finish()
    rc, out, err = _run([*cmd, str(path)])
    assert rc == 2 and out == "" and list(tmp_path.iterdir()) == [path]
    assert err == f"bev-mdo {cmd[0]}: error: {path}: holds no bev_mdo run (no bev_mdo_msgs topic, no run record)\n"
