"""A closed pipe (`bev-mdo ... | head`) ends the command quietly: no traceback, exit status 141."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_graph_into_a_closed_pipe_prints_no_traceback():
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    # stdout is a pipe whose reader is gone before the command writes
    r, w = os.pipe()
    os.close(r)
    proc = subprocess.run([sys.executable, "-c", "import sys; from bev_mdo.cli import main; sys.exit(main())",
                           "graph", str(ROOT / "config/leaf_nedc.yaml")],
                          stdout=w, stderr=subprocess.PIPE, text=True, env=env, timeout=120)
    os.close(w)
    assert "Traceback" not in proc.stderr and "BrokenPipe" not in proc.stderr, proc.stderr
    assert proc.returncode == 141
