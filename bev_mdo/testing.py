"""Helpers for tests of bev_mdo and of users' own disciplines: ROS domains and environments.

Every process a test starts gets localhost-only discovery and a domain id of its own.
"""
from __future__ import annotations

import os
import sys
import time
import zlib
from pathlib import Path

from bev_mdo.ros_settings import DEFAULTS, ros_environment

REPO = Path(__file__).resolve().parents[1]
PYTHON = sys.executable


def domain_for(name: str) -> int:
    """A stable ROS domain id per test module, in 100..199 (away from the default 77)."""
    return 100 + zlib.crc32(name.encode()) % 100


def ros_env(domain_id: int) -> dict[str, str]:
    """Environment for a child process: localhost-only discovery on its own domain."""
    env = ros_environment({**DEFAULTS, "domain_id": domain_id})
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    env["PYTHONUNBUFFERED"] = "1"
    return env


def wait_until(predicate, timeout_s: float = 30.0, step=None, every_s: float = 0.02) -> bool:
    """Call `predicate` until it is true (True) or `timeout_s` passed (False); in between `step()`
    (e.g. spin an executor once) or a sleep of `every_s`. Tests wait for conditions, not for time."""
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() >= deadline:
            return False
        step() if step is not None else time.sleep(every_s)
    return True


def child_processes(pid: int) -> dict[int, str]:
    """The direct children of process `pid` (Linux /proc) with their command lines."""
    out = {}
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            children = (task / "children").read_text().split()
        except OSError:  # the thread ended since the listing (a run that is shutting down)
            continue
        for child in children:
            try:
                out[int(child)] = Path(f"/proc/{child}/cmdline").read_bytes().decode(errors="replace")
            except OSError:
                pass
    return out


def leaf_config_file(directory: str | Path, ros: dict, name: str = "leaf.yaml") -> Path:
    """``config/leaf_nedc.yaml`` with its ``ros:`` section replaced by `ros`, written to `directory/name`
    (what a fault or transport test runs ``bev-mdo optimize`` or its nodes on)."""
    import yaml

    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["ros"] = dict(ros)
    path = Path(directory) / name
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


def example_config(path: str | Path, **changes):
    """Load an example config (e.g. ``examples/ssbj/ssbj_mdf.yaml``) with dotted-key changes
    (``optimizer.name="COBYQA"``) and its own folder as the search path for ``module:Class``."""
    import yaml

    from bev_mdo.config import load_config

    path = Path(path)
    raw = yaml.safe_load(path.read_text())
    for dotted, value in changes.items():
        node = raw
        keys = dotted.split(".")
        for k in keys[:-1]:
            node = node.setdefault(k, {})
        node[keys[-1]] = value
    raw["search_path"] = [str(path.parent)]
    return load_config(raw)


def assert_same_iterates(ros, local) -> None:
    """The ROS run `ros` took the in-process run's path: the same iteration records (design and objective
    to 1e-12) and the same discipline evaluations (two RunResults)."""
    import pytest

    assert len(ros.history) == len(local.history)
    for a, b in zip(ros.history, local.history):
        assert a["design"].keys() == b["design"].keys()
        for k in a["design"]:
            assert a["design"][k] == pytest.approx(b["design"][k], rel=1e-12, abs=1e-12)
        assert a["objective"] == pytest.approx(b["objective"], rel=1e-12, nan_ok=True)  # NaN: a failed point
    assert ros.discipline_evaluations == local.discipline_evaluations


def end_outside_a_bound(monkeypatch, index: int, value: float) -> None:
    """The driver's optimiser (``driver.run_optimizer``, patched through pytest's `monkeypatch`) ends at its
    own result with optimiser variable `index` set to `value` and recorded as an iteration: what COBYLA did,
    ending Sellar 5e-8 below z2 >= 0 and SSBJ 6e-5 above x_shared[1] <= 60000 (a result just outside a bound)."""
    import numpy as np

    from bev_mdo.mdo import driver

    inner = driver.run_optimizer

    def ending_outside(name, form, options, record):
        res = inner(name, form, options, record)
        res.x = np.asarray(res.x, float).copy()
        res.x[index] = value
        record(res.x)
        return res

    monkeypatch.setattr(driver, "run_optimizer", ending_outside)
