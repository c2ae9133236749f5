"""An output file that cannot be written (its folder missing, a directory given) is one line naming
the file and the reason, exit status 2 - not a raw ``[Errno 2] No such file or directory: ...``."""
from __future__ import annotations

import contextlib
import io
from pathlib import Path

import pytest

from bev_mdo.cli import main

CONFIG = str(Path(__file__).resolve().parents[2] / "config/leaf_nedc.yaml")


def _error_line(capsys, *argv) -> str:
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(list(argv)) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if ": error: " in line]
    assert len(err) == 1, err
    assert "Errno" not in err[0], err[0]
    return err[0]


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    bag = tmp_path_factory.mktemp("history") / "bag"
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["optimize", CONFIG, "--transport", "inprocess", "--bag", str(bag), "--quiet"]) == 0
    return bag


def test_history_csv_into_a_missing_folder_names_file_and_folder(bag, tmp_path, capsys):
    target = tmp_path / "no such folder" / "x.csv"
    line = _error_line(capsys, "history", str(bag), "--csv", str(target))
    assert line == f"bev-mdo history: error: cannot write {target}: the folder {target.parent} does not exist"


def test_history_csv_onto_a_directory_says_so(bag, tmp_path, capsys):
    line = _error_line(capsys, "history", str(bag), "--csv", str(tmp_path))
    assert line.startswith(f"bev-mdo history: error: cannot write {tmp_path}: it is a directory")


@pytest.mark.parametrize("flag", ["--dot", "--png"])
def test_graph_output_into_a_missing_folder_names_file_and_folder(flag, tmp_path, capsys):
    target = tmp_path / "missing" / ("n2.dot" if flag == "--dot" else "n2.png")
    line = _error_line(capsys, "graph", CONFIG, flag, str(target))
    assert line == f"bev-mdo graph: error: cannot write {target}: the folder {target.parent} does not exist"


@pytest.mark.parametrize("argv", [["history", "{bag}", "--csv", "/dev/stdout"], ["graph", CONFIG, "--dot", "/dev/stdout"]])
def test_dev_stdout_is_stdout_like_a_dash(bag, argv):
    """bev-mdo points descriptor 1 at stderr while it runs (native_output_to_stderr), so
    ``history --csv /dev/stdout`` wrote the CSV to stderr (a user trial); it is written like ``-``."""
    import subprocess

    from bev_mdo.testing import PYTHON, REPO

    argv = [a.replace("{bag}", str(bag)) for a in argv]
    dash = subprocess.run([PYTHON, "-m", "bev_mdo", *argv[:-1], "-"], cwd=REPO, capture_output=True, text=True, timeout=120)
    dev = subprocess.run([PYTHON, "-m", "bev_mdo", *argv], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert dash.returncode == dev.returncode == 0, dev.stderr
    assert dash.stdout.strip() and dev.stdout == dash.stdout
    assert dev.stderr == dash.stderr


@pytest.mark.parametrize("argv", [["graph", CONFIG, "--png", "/dev/stdout"],
                                  ["sensitivity", CONFIG, "--at", "motor_kw=80", "--order", "1", "--transport",
                                   "inprocess", "--png", "-"]])
def test_a_png_to_standard_output_is_refused_in_one_line(argv, tmp_path):
    """``graph --png /dev/stdout`` wrote the PNG to stderr (descriptor 1 points there while bev-mdo runs),
    exit 0; ``-`` was a file named '-'. A binary image does not go among a command's text: one line, exit 2,
    before anything is computed."""
    import subprocess

    from bev_mdo.testing import PYTHON, REPO

    run = subprocess.run([PYTHON, "-m", "bev_mdo", *argv], cwd=tmp_path, capture_output=True, timeout=120,
                         env={**__import__("os").environ, "PYTHONPATH": str(REPO)})
    err = run.stderr.decode(errors="replace")
    assert run.returncode == 2 and run.stdout == b"" and not list(tmp_path.iterdir()), err
    assert err == (f"bev-mdo {argv[0]}: error: --png {argv[-1]}: a PNG is binary, not written to standard output; "
                   "give a file name, e.g. plot.png\n")


@pytest.mark.parametrize("png, refused", [("/dev/stderr", True), ("/dev/fd/2", True), ("./-", False)])
def test_a_png_to_standard_error_is_refused_and_a_file_named_dash_written(png, refused, tmp_path):
    """``--png /dev/stderr`` wrote the image's bytes among the command's messages (to the terminal), exit 0;
    ``--png ./-`` (a file named '-', as the shell's way to say so) was refused as standard output."""
    import subprocess

    from bev_mdo.testing import PYTHON, REPO

    run = subprocess.run([PYTHON, "-m", "bev_mdo", "graph", CONFIG, "--png", png], cwd=tmp_path, capture_output=True,
                         timeout=120, env={**__import__("os").environ, "PYTHONPATH": str(REPO)})
    err = run.stderr.decode(errors="replace")
    if refused:
        assert run.returncode == 2 and err == (f"bev-mdo graph: error: --png {png}: a PNG is binary, not written to "
                                               "standard error or a terminal; give a file name, e.g. plot.png\n")
    else:
        assert run.returncode == 0 and (tmp_path / "-").read_bytes().startswith(b"\x89PNG"), err
