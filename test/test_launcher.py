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
