"""The launcher's node processes: where they sit among the host's sessions and process groups.

A node gets a process group of its own (a Ctrl-C in the terminal reaches only the command, which
stops its nodes in order) but stays in the command's session: Linux schedules by session
(autogroups), and with a session per node eight runs started from one shell were starved against
their own 64 nodes and did not start (docs/scaling.md).
"""
from __future__ import annotations

import os
import sys

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
