"""A closed pipe (`bev-mdo ... | head`) ends the command quietly: no traceback, exit status 141.

The rich tables (evaluate, history, compare) are written through rich's Console, which turns a
closed pipe into SystemExit(1) - an exit status that means "evaluation failed" for evaluate."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CONFIG = str(ROOT / "config/leaf_nedc.yaml")
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}


def _into_closed_pipe(*argv: str) -> subprocess.CompletedProcess:
    """``bev-mdo ARGV`` with stdout a pipe whose reader is gone before the command writes."""
    r, w = os.pipe()
    os.close(r)
    try:
        return subprocess.run([sys.executable, "-c", "import sys; from bev_mdo.cli import main; sys.exit(main())",
                               *argv], stdout=w, stderr=subprocess.PIPE, text=True, env=ENV, timeout=300)
    finally:
        os.close(w)


def _assert_quiet_141(proc: subprocess.CompletedProcess) -> None:
    assert "Traceback" not in proc.stderr and "BrokenPipe" not in proc.stderr, proc.stderr
    assert "error" not in proc.stderr, proc.stderr
    assert proc.returncode == 141, (proc.returncode, proc.stderr)


def test_graph_into_a_closed_pipe_prints_no_traceback():
    _assert_quiet_141(_into_closed_pipe("graph", CONFIG))


@pytest.mark.parametrize("argv", [
    ("evaluate", CONFIG, "--transport", "inprocess"),
    ("compare", CONFIG, "--transport", "inprocess", "--design", "motor_kw=80", "--design", "motor_kw=100"),
], ids=["evaluate-table", "compare"])
def test_rich_table_into_a_closed_pipe_exits_141(argv):
    _assert_quiet_141(_into_closed_pipe(*argv))


def test_history_table_into_a_closed_pipe_exits_141(tmp_path):
    bag = tmp_path / "bag"
    made = subprocess.run([sys.executable, "-m", "bev_mdo", "optimize", CONFIG, "--transport", "inprocess",
                           "--bag", str(bag), "--quiet"], capture_output=True, text=True, env=ENV, timeout=300)
    assert made.returncode == 0, made.stderr
    _assert_quiet_141(_into_closed_pipe("history", str(bag)))
