"""The optimisers reach the published optima under every OpenBLAS kernel this CPU runs, not only the
one OpenBLAS picks here: the reaching tests are re-run in a subprocess with OPENBLAS_CORETYPE set.

By default two kernels run (the two supported ones first in KERNELS that differ from what OpenBLAS
picks by default, so with the plain run of the suite that makes three); BEV_MDO_KERNELS=all runs every
supported kernel, BEV_MDO_KERNELS=Zen,Haswell the named ones."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
# kernel -> the CPU flags (/proc/cpuinfo) it needs
KERNELS = {"Sandybridge": {"avx"}, "Haswell": {"avx2", "fma"}, "Zen": {"avx2", "fma"}, "SkylakeX": {"avx512f"}}
REACHING = [
    "test/mdo/test_sellar_suite.py::test_sellar_reaches_the_published_optimum",
    "test/mdo/test_vectors.py::test_vector_sellar_reaches_its_published_optimum",
    "test/mdo/test_aerostructure.py::test_other_optimisers_that_reach_the_maximum",
    "test/mdo/test_ssbj.py::test_ssbj_reaches_the_reference_optimum_with_slsqp",
    "test/mdo/test_ssbj.py::test_other_optimisers_that_reach_the_optimum",
]
# OpenBLAS runs Zen on its Haswell kernels (OPENBLAS_VERBOSE=2 then says "Core: Haswell")
CORE_NAME = {"Zen": "Haswell"}


def _cpu_flags() -> set[str]:
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return set()
    for line in text.splitlines():
        if line.startswith("flags"):
            return set(line.split(":", 1)[1].split())
    return set()


def _core(env: dict) -> str:
    """The kernel OpenBLAS says it runs (OPENBLAS_VERBOSE=2) in a fresh interpreter with ``env``."""
    proc = subprocess.run([sys.executable, "-c", "import numpy"], env={**env, "OPENBLAS_VERBOSE": "2"},
                          capture_output=True, text=True, timeout=120)
    return next((line.split(":", 1)[1].strip() for line in (proc.stdout + proc.stderr).splitlines()
                 if line.startswith("Core:")), "")


def _default_kernel() -> str:
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_CORETYPE"}
    return _core(env)


def _chosen() -> list[str]:
    flags = _cpu_flags()
    supported = [k for k, need in KERNELS.items() if need <= flags]
    wish = os.environ.get("BEV_MDO_KERNELS", "")
    if wish == "all":
        return supported
    if wish:
        return [k for k in wish.split(",") if k in supported]
    default = _default_kernel()
    return [k for k in supported if CORE_NAME.get(k, k) != default][:2]


@pytest.mark.slow
@pytest.mark.parametrize("kernel", _chosen() or [pytest.param("none", marks=pytest.mark.skip("no known kernel"))])
def test_optimisers_reach_the_published_optima_under_the_kernel(kernel):
    env = {**os.environ, "OPENBLAS_CORETYPE": kernel}
    assert _core(env) == CORE_NAME.get(kernel, kernel)  # OpenBLAS runs the kernel asked for
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider", *REACHING],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stdout[-4000:]


ROS_REACHING = ["test/ros/test_sellar_ros.py::test_sellar_over_ros_gives_the_in_process_iterates_and_the_reference"]


@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.parametrize("kernel", _chosen() or [pytest.param("none", marks=pytest.mark.skip("no known kernel"))])
def test_optimisers_over_ros_reach_the_published_optimum_under_the_kernel(kernel):
    """Sellar MDF and IDF with SLSQP, COBYQA, COBYLA and trust-constr over ROS (the coordinator here, the
    discipline nodes in their own processes, every one under the kernel): the in-process iterates and
    the published optimum."""
    env = {**os.environ, "OPENBLAS_CORETYPE": kernel}
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider", *ROS_REACHING],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stdout[-4000:]
