"""The standard ROS build: `colcon build` of both packages in a fresh workspace."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from bev_mdo.testing import REPO

VENV = Path(sys.prefix)
COLCON = VENV / "bin" / "colcon"


@pytest.mark.slow
@pytest.mark.skipif(not COLCON.exists(), reason="colcon is not installed in this environment")
def test_colcon_builds_both_packages(tmp_path):
    src = tmp_path / "ws" / "src"
    pkg = src / "bev_mdo"
    pkg.mkdir(parents=True)
    for item in ("package.xml", "setup.py", "setup.cfg", "resource", "ros_lib", "config", "bev_mdo"):
        s = REPO / item
        (shutil.copytree if s.is_dir() else shutil.copy)(s, pkg / item)
    shutil.copytree(REPO / "msg_defs", src / "bev_mdo_msgs")
    env = dict(os.environ)
    env["AMENT_PREFIX_PATH"] = str(VENV)
    env["CMAKE_PREFIX_PATH"] = str(VENV)
    env["PATH"] = f"{VENV / 'bin'}{os.pathsep}{env['PATH']}"
    out = subprocess.run(
        [str(COLCON), "build", "--cmake-args", "-DBUILD_TESTING=OFF", f"-DPython3_EXECUTABLE={sys.executable}"],
        cwd=tmp_path / "ws", env=env, capture_output=True, text=True, timeout=900,
    )
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    install = tmp_path / "ws" / "install"
    # bev_mdo: registered in the ament index, node executables in lib/bev_mdo
    assert (install / "bev_mdo" / "share" / "ament_index" / "resource_index" / "packages" / "bev_mdo").is_file()
    for exe in ("energy_node", "coordinator_node", "recorder_node"):
        assert os.access(install / "bev_mdo" / "lib" / "bev_mdo" / exe, os.X_OK), exe
    # bev_mdo_msgs: generated Python messages importable from the install space
    site = next((install / "bev_mdo_msgs" / "lib").glob("python3*/site-packages"))
    check = subprocess.run(
        [sys.executable, "-c", "import bev_mdo_msgs; from bev_mdo_msgs.msg import EvaluationRequest; "
         "print(EvaluationRequest().attempt, bev_mdo_msgs.__file__)"],
        env={**env, "PYTHONPATH": str(site)}, capture_output=True, text=True, cwd=tmp_path,
    )
    assert check.returncode == 0, check.stderr[-2000:]
    attempt, where = check.stdout.split()
    assert attempt == "0" and where.startswith(str(install)), where
