"""Bad input gets one line on stderr and exit 2, within bounded memory and time: YAML alias bombs,
deep nesting, binary files, run names that escape bags/, huge vectors and sweeps, a bag path under
a file, numbers no optimiser can take. A discipline's sys.exit is a named discipline failure."""
from __future__ import annotations

import os
import resource
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from bev_mdo.testing import REPO

HERE = Path(__file__).resolve().parent
MEMORY_BYTES = 3 * 1024 ** 3


def _limits():
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_BYTES, MEMORY_BYTES))


def _bev_mdo(cwd: Path, *argv: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": f"{HERE}{os.pathsep}{REPO}"}
    return subprocess.run([sys.executable, "-m", "bev_mdo", *argv], capture_output=True, text=True, env=env,
                          timeout=120, cwd=cwd, preexec_fn=_limits)


def _config(tmp_path: Path, text: str | None = None, **changes) -> Path:
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw.update(changes)
    path = tmp_path / "bad.yaml"
    path.write_text(text if text is not None else yaml.safe_dump(raw, sort_keys=False))
    return path


def _one_line_exit_2(p: subprocess.CompletedProcess, *words: str) -> str:
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1, (p.returncode, p.stderr[-3000:])
    assert "Traceback" not in p.stderr
    for w in words:
        assert w in lines[0], lines[0]
    return lines[0]


def _leaf_text() -> str:
    return (REPO / "config" / "leaf_nedc.yaml").read_text()


def _bomb(levels: int = 9) -> str:
    lines = ['    l0: &l0 ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for i in range(1, levels + 1):
        lines.append(f"    l{i}: &l{i} [" + ",".join([f"*l{i - 1}"] * 9) + "]")
    return "\n".join(lines)


def test_a_yaml_alias_bomb_in_a_disciplines_options(tmp_path):
    text = _leaf_text() + ("disciplines:\n  - vehicle_mass\n  - range\n  - acceleration\n  - motor_speed\n"
                           "  - name: energy\n    options:\n      junk:\n"
                           + "\n".join("  " + l for l in _bomb().splitlines()) + "\n")
    p = _bev_mdo(tmp_path, "optimize", str(_config(tmp_path, text)), "--transport", "inprocess", "--no-record")
    _one_line_exit_2(p, "bad.yaml", "aliases are expanded", "alias bomb")


def _ros_limits():
    resource.setrlimit(resource.RLIMIT_AS, (ROS_MEMORY_BYTES, ROS_MEMORY_BYTES))


ROS_MEMORY_BYTES = 4 * 1024 ** 3  # a ROS process maps more address space than a plain one


@pytest.mark.parametrize("argv", [["optimize", "CONFIG", "--bag", "b"], ["node", "energy", "--config", "CONFIG"]],
                         ids=["optimize", "node"])
def test_a_yaml_alias_bomb_in_a_disciplines_options_over_ros(tmp_path, ros_domain, argv):
    """Over ROS (a run that launches its nodes, and a discipline node started by hand) the same bomb is refused
    before anything starts: one line, exit 2, within 4 GB and 120 s; nothing written."""
    from bev_mdo.testing import ros_env

    text = _leaf_text() + ("disciplines:\n  - vehicle_mass\n  - range\n  - acceleration\n  - motor_speed\n"
                           "  - name: energy\n    options:\n      junk:\n"
                           + "\n".join("  " + l for l in _bomb().splitlines()) + "\n")
    config = str(_config(tmp_path, text))
    work = tmp_path / "work"
    work.mkdir()
    env = {**ros_env(ros_domain), "PYTHONPATH": f"{HERE}{os.pathsep}{REPO}"}
    p = subprocess.run([sys.executable, "-m", "bev_mdo", *[config if a == "CONFIG" else a for a in argv],
                        "--domain-id", str(ros_domain)], capture_output=True, text=True, env=env, timeout=120,
                       cwd=work, preexec_fn=_ros_limits)
    _one_line_exit_2(p, "bad.yaml", "aliases are expanded", "alias bomb")
    assert os.listdir(work) == []


def test_deeply_nested_yaml(tmp_path):
    text = _leaf_text() + "recording: " + "[" * 5000 + "]" * 5000 + "\n"
    p = _bev_mdo(tmp_path, "optimize", str(_config(tmp_path, text)), "--transport", "inprocess", "--no-record")
    _one_line_exit_2(p, "bad.yaml", "nested deeper than")


def test_a_binary_file_given_as_config(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_bytes(bytes(range(256)) * 4)
    p = _bev_mdo(tmp_path, "optimize", str(path), "--transport", "inprocess", "--no-record")
    _one_line_exit_2(p, "bad.yaml", "not a YAML text file")


@pytest.mark.parametrize("name", ["../x", "../../escaped_run", "a/b", ".."])
def test_a_run_name_that_leaves_bags_is_refused_and_nothing_is_left(tmp_path, name):
    work = tmp_path / "work"
    work.mkdir()
    p = _bev_mdo(work, "optimize", str(_config(tmp_path, name=name)), "--transport", "inprocess",
                 "--bag", "bags/b")
    _one_line_exit_2(p, "name", "no path separator")
    assert sorted(os.listdir(work)) == [] and sorted(os.listdir(tmp_path)) == ["bad.yaml", "work"]


def test_pareto_refuses_a_run_name_that_leaves_bags(tmp_path):
    work = tmp_path / "work"
    work.mkdir()
    p = _bev_mdo(work, "pareto", str(_config(tmp_path, name="../escaped")), "--generations", "1", "--pop", "4",
                 "--transport", "inprocess")
    _one_line_exit_2(p, "name")
    assert os.listdir(work) == [] and sorted(os.listdir(tmp_path)) == ["bad.yaml", "work"]


def test_a_huge_vector_shape(tmp_path):
    raw = yaml.safe_load(_leaf_text())
    raw["problem"]["design_variables"]["motor_kw"]["shape"] = 10 ** 9
    p = _bev_mdo(tmp_path, "optimize", str(_config(tmp_path, problem=raw["problem"])), "--transport", "inprocess",
                 "--no-record")
    _one_line_exit_2(p, "shape", "at most")


def test_a_400_digit_number(tmp_path):
    text = _leaf_text().replace("motor_kw:    {lower: 40,", "motor_kw:    {lower: " + "9" * 400 + ",")
    assert "9" * 400 in text
    p = _bev_mdo(tmp_path, "optimize", str(_config(tmp_path, text)), "--transport", "inprocess", "--no-record")
    _one_line_exit_2(p, "bad.yaml", "400 digits", "line 26")


def test_a_sweep_of_a_billion_points(tmp_path):
    p = _bev_mdo(tmp_path, "sweep", str(REPO / "config" / "leaf_nedc.yaml"), "--vary", "motor_kw=40:120:1000000000",
                 "--no-plots", "--transport", "inprocess")
    _one_line_exit_2(p, "at most")
    p = _bev_mdo(tmp_path, "sweep", str(REPO / "config" / "leaf_nedc.yaml"), "--vary", "motor_kw=40:120:1000",
                 "gear_ratio=2:10:1000", "battery_kwh=20:30:1000", "--no-plots", "--transport", "inprocess")
    _one_line_exit_2(p, "at most")


def test_a_multistart_of_a_billion_starts(tmp_path):
    """--starts 100000000 ran 9 s, then a MemoryError (exit 7): the sample alone was 2.4 GB."""
    p = _bev_mdo(tmp_path, "optimize", str(REPO / "config" / "leaf_nedc.yaml"), "--starts", "1000000000",
                 "--transport", "inprocess", "--no-record")
    _one_line_exit_2(p, "--starts 1000000000: at most 10,000")


@pytest.mark.parametrize("command", [["optimize", "--starts", "3"], ["sweep", "--doe", "lhs", "--no-plots"],
                                     ["pareto", "--pop", "4", "--generations", "1"],
                                     ["sensitivity", "--global", "morris"]])
def test_a_negative_seed_is_refused_naming_the_flag(tmp_path, command):
    """numpy's "expected non-negative integer" named no flag (and came after the nodes had started)."""
    p = _bev_mdo(tmp_path, command[0], str(REPO / "config" / "leaf_nedc.yaml"), *command[1:], "--seed", "-1",
                 "--transport", "inprocess")
    _one_line_exit_2(p, "argument --seed: -1: give a whole number >= 0")


def test_a_bag_path_under_an_existing_file(tmp_path):
    (tmp_path / "afile").write_text("x")
    p = _bev_mdo(tmp_path, "optimize", str(REPO / "config" / "leaf_nedc.yaml"), "--transport", "inprocess",
                 "--bag", str(tmp_path / "afile" / "bag"))
    _one_line_exit_2(p, "afile")


@pytest.mark.parametrize("maxiter, said", [("ten", "'ten' is not a number"),
                                            # accepted: the run did no iteration and exited 5
                                            (-5, "-5 must be a whole number of at least 1"),
                                            (2.5, "2.5 must be a whole number of at least 1")])
def test_maxiter_that_is_no_count(tmp_path, maxiter, said):
    p = _bev_mdo(tmp_path, "optimize", str(_config(tmp_path, optimizer={"name": "SLSQP",
                                                                          "options": {"maxiter": maxiter}})),
                 "--transport", "inprocess", "--no-record")
    _one_line_exit_2(p, "optimizer.options.maxiter", said)


def test_a_discipline_calling_sys_exit_is_a_named_failure(tmp_path):
    raw = yaml.safe_load(_leaf_text())
    raw["disciplines"] = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed",
                          {"name": "quits", "class": "bad_disciplines:Quits"}]
    raw["problem"]["constraints"]["quits_kw"] = {"upper": 1.0e9}
    raw["optimizer"] = {"name": "SLSQP", "options": {"maxiter": 2}}
    p = _bev_mdo(tmp_path, "optimize", str(_config(tmp_path, **raw)), "--transport", "inprocess", "--no-record")
    assert p.returncode == 1, p.stderr[-2000:]  # every point failed: infeasible, the run reported
    named = [l for l in p.stderr.splitlines() if l.startswith("discipline 'quits' failed:")]
    assert len(named) == 1 and "sys.exit(3)" in named[0], p.stderr[-2000:]
