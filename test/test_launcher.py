"""The launcher's node processes: where they sit among the host's sessions and process groups.

A node gets a process group of its own (a Ctrl-C in the terminal reaches only the command, which
stops its nodes in order) but stays in the command's session: Linux schedules by session
(autogroups), and with a session per node eight runs started from one shell were starved against
their own 64 nodes and did not start (docs/scaling.md).
"""
from __future__ import annotations

import os
import signal
import sys
import threading
import time

import pytest

from bev_mdo import interrupts
from bev_mdo.launcher import Launcher


def test_a_node_has_its_own_process_group_in_the_commands_session(tmp_path):
    launcher = Launcher(dict(os.environ), log_dir=tmp_path)
    try:
        node = launcher.add("sleeper", [sys.executable, "-c", "import time; time.sleep(60)"], restart=False)
        pid = node.proc.pid
        assert os.getsid(pid) == os.getsid(0)  # the command's session: one CPU share for the run
        assert os.getpgid(pid) == pid != os.getpgrp()  # a group of its own: the terminal's Ctrl-C is ours
    finally:
        launcher.stop(timeout_s=5.0)
    assert node.proc.poll() is not None


def test_a_second_ctrl_c_while_the_nodes_stop_still_kills_a_node_deaf_to_signals(tmp_path):
    """A node busy in one long numba/numpy call runs no Python signal handler: SIGINT and SIGTERM do nothing,
    only the SIGKILL at the end of Launcher.stop ends it. A second Ctrl-C during that stop cut it short: the
    command ended (exit 130) and left the node running, orphaned, and its suite's folder behind (a user
    trial: `sweep --samples 300000` over ROS). The stop now finishes first, then the signal is raised."""
    deaf = ("import signal, time\n"
            "for s in (signal.SIGINT, signal.SIGTERM, signal.SIGUSR1): signal.signal(s, signal.SIG_IGN)\n"
            "print('ready', flush=True)\n"
            "while True: time.sleep(0.05)\n")
    launcher = Launcher(dict(os.environ), log_dir=tmp_path)
    node = launcher.add("busy", [sys.executable, "-c", deaf], restart=False)
    deadline = time.monotonic() + 60
    while "ready" not in (tmp_path / "busy.log").read_text() and time.monotonic() < deadline:
        time.sleep(0.05)
    previous = interrupts.install()
    second = threading.Timer(1.0, os.kill, (os.getpid(), signal.SIGINT))  # while stop waits after its SIGINT
    try:
        second.start()
        with pytest.raises(KeyboardInterrupt):
            launcher.stop(timeout_s=3.0)
        left_running = node.proc.poll() is None
    finally:
        second.cancel()
        interrupts.restore(previous)
        if node.proc.poll() is None:  # never leave it behind, whatever happened
            node.proc.kill()
            node.proc.wait()
    assert not left_running, "the node deaf to SIGINT and SIGTERM outlived the interrupted stop"


def test_a_node_killed_and_restarted_is_recovering_until_it_is_back_on_the_graph(tmp_path):
    """What the coordinator's retries wait for past their budget (Orchestrator.recovering)."""
    launcher = Launcher(dict(os.environ), log_dir=tmp_path)
    try:
        node = launcher.add("vehicle_mass+energy", [sys.executable, "-c", "import time; time.sleep(60)"])
        node.seen = True  # on the graph, as the watchdog marks it
        assert not launcher.recovering("energy")
        launcher.supervise()
        launcher.kill("vehicle_mass+energy")
        assert launcher.recovering("energy") and launcher.recovering("vehicle_mass")  # dead or restarted
        assert not launcher.recovering("range")
        deadline = time.monotonic() + 30
        while node.restarts == 0 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert node.restarts == 1 and launcher.recovering("energy")  # restarted, not yet seen
        node.seen = True
        assert not launcher.recovering("energy")
    finally:
        launcher.stop(timeout_s=5.0)


def _ignored(pid: int) -> int:
    """The signals process `pid` ignores (the SigIgn mask of /proc/PID/status)."""
    line = next(ln for ln in open(f"/proc/{pid}/status") if ln.startswith("SigIgn:"))
    return int(line.split()[1], 16)


def test_a_node_of_a_launcher_that_ignores_sigint_takes_the_first_signal(tmp_path):
    """A shell's background job (`bev-mdo optimize ... &` in a script) inherits SIGINT ignored: so did its nodes, and
    Launcher.stop's SIGINT reached none of them (SIGUSR1 and SIGTERM after 30 s, a stack dump in the recorder's log).
    The nodes start with SIGINT and SIGTERM at their defaults, and stop at the first SIGINT."""
    ignored = (signal.SIGINT, signal.SIGTERM)
    previous = {s: signal.signal(s, signal.SIG_IGN) for s in ignored}  # as the command inherited them
    launcher = Launcher(dict(os.environ), log_dir=tmp_path)
    try:
        node = launcher.add("sleeper", [sys.executable, "-c", "import time; time.sleep(600)"], restart=False)
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
    try:
        assert _ignored(node.proc.pid) & sum(1 << (s - 1) for s in ignored) == 0  # (Python keeps an inherited SIG_IGN)
    finally:
        launcher.stop(timeout_s=5.0)
    assert node.proc.returncode == -signal.SIGINT  # the first signal, not SIGUSR1 (then SIGTERM) after the wait
    assert "most recent call first" not in (tmp_path / "sleeper.log").read_text()


def test_the_log_folder_a_run_gave_this_process_is_taken_back_when_it_stops(tmp_path, monkeypatch):
    """An API trial: after one ROS run, os.environ kept ROS_LOG_DIR=<first run's bag>/logs/ros, so a later run of
    the same Python session logged into the first one's folder. One the caller set stays as it was."""
    monkeypatch.delenv("ROS_LOG_DIR", raising=False)
    with Launcher(dict(os.environ), log_dir=tmp_path / "run1" / "logs"):
        assert os.environ["ROS_LOG_DIR"] == str((tmp_path / "run1" / "logs" / "ros").resolve())
    assert "ROS_LOG_DIR" not in os.environ
    monkeypatch.setenv("ROS_LOG_DIR", str(tmp_path / "mine"))
    with Launcher(dict(os.environ), log_dir=tmp_path / "run2" / "logs"):
        pass
    assert os.environ["ROS_LOG_DIR"] == str(tmp_path / "mine")
