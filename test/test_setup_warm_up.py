"""scripts/setup.sh compiles the quasi-static model's numba loops for the installed package, the copy that
bev-mdo and the node executables import (a user trial: setup.sh run from the repository warmed only the source
tree's cache, and a first ROS sweep's energy node compiled for about a minute and start-up gave up)."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
WARM = "from bev_mdo.disciplines.energy import warm_up; warm_up()"


def test_setup_warms_the_installed_package_and_the_source_tree():
    text = (ROOT / "scripts" / "setup.sh").read_text()
    lines = [x for x in text.splitlines() if WARM in x]
    assert lines
    venv = Path(sys.prefix)
    installed = subprocess.run([str(venv / "bin" / "python"), "-I", "-c", "import bev_mdo; print(bev_mdo.__file__)"],
                               cwd="/", capture_output=True, text=True, check=True).stdout.strip()
    seen = set()
    for line in lines:  # each warm-up command, run as setup.sh runs it from the repository, printing what it imports
        cmd = re.sub(r"\\s*$", "", line.strip()).removeprefix("&&").strip().rstrip("\\").strip()
        cmd = cmd.replace(WARM, "import bev_mdo; print(bev_mdo.__file__)")
        env = {**os.environ, "VENV": str(venv), "ROOT": str(ROOT)}
        out = subprocess.run(["bash", "-c", cmd], cwd=ROOT, env=env, capture_output=True, text=True, check=True)
        seen.add(str(Path(out.stdout.strip()).resolve()))
    assert str(Path(installed).resolve()) in seen  # what the node executables import
