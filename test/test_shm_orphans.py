"""Fast DDS shared-memory files of dead processes are removed at start; a live owner's are kept."""
from __future__ import annotations

import fcntl
import os
import time

from bev_mdo.shm import remove_orphans
from bev_mdo.testing import wait_until


def _files(d, *names, age_s=60.0):
    t = time.time() - age_s
    for n in names:
        (d / n).write_bytes(b"")
        os.utime(d / n, (t, t))


def test_only_groups_whose_locks_nobody_holds_are_removed(tmp_path):
    dead, live, young = "fastrtps_0123456789abcdef", "fastrtps_fedcba9876543210", "fastrtps_00000000000000aa"
    port = "fastrtps_port7411"
    _files(tmp_path, dead, f"{dead}_el", live, f"{live}_el", port, f"{port}_el", f"{port}_sl",
           f"sem.{port}_mutex", "unrelated_el", "fastrtps_0123456789abcdef.txt")
    _files(tmp_path, young, f"{young}_el", age_s=0.0)  # a participant creating its files right now
    with open(tmp_path / f"{live}_el", "rb") as held:
        fcntl.flock(held, fcntl.LOCK_SH)  # as a live participant holds its lock
        removed = remove_orphans(tmp_path, min_age_s=5.0)
        assert (tmp_path / live).exists() and (tmp_path / f"{live}_el").exists()
    assert sorted(removed) == sorted([dead, f"{dead}_el", port, f"{port}_el", f"{port}_sl", f"sem.{port}_mutex"])
    left = sorted(p.name for p in tmp_path.iterdir())
    assert left == sorted([live, f"{live}_el", young, f"{young}_el", "unrelated_el", "fastrtps_0123456789abcdef.txt"])


def test_a_port_with_one_lock_still_held_is_kept(tmp_path):
    port = "fastrtps_port7415"
    _files(tmp_path, port, f"{port}_el", f"{port}_sl")
    with open(tmp_path / f"{port}_sl", "rb") as held:
        fcntl.flock(held, fcntl.LOCK_SH)
        assert remove_orphans(tmp_path) == []
    assert remove_orphans(tmp_path) == [port, f"{port}_el", f"{port}_sl"]


def test_a_missing_directory_is_no_error(tmp_path):
    assert remove_orphans(tmp_path / "absent") == []


def test_a_node_the_launcher_had_to_kill_leaves_no_files(tmp_path):
    """Launcher.stop removes the Fast DDS files of the nodes it SIGTERMed or SIGKILLed (a recorder still in its
    ROS teardown past the stop's wait), not only the next start: a run leaves nothing of its own behind."""
    import signal
    import sys
    from pathlib import Path

    from bev_mdo.launcher import Launcher

    name = f"fastrtps_bevtest{os.getpid():x}"
    shm = Path("/dev/shm")
    code = "\n".join([
        "import fcntl, os, signal, time", "signal.signal(signal.SIGINT, signal.SIG_IGN)",
        f"open('/dev/shm/{name}', 'wb').close()", f"lock = open('/dev/shm/{name}_el', 'wb')",
        "fcntl.flock(lock, fcntl.LOCK_EX)", "t = time.time() - 60",
        f"os.utime('/dev/shm/{name}', (t, t)); os.utime('/dev/shm/{name}_el', (t, t))",
        "print('ready', flush=True)", "time.sleep(120)"])
    la = Launcher({}, log_dir=tmp_path)
    try:
        node = la.add("stuck", [sys.executable, "-c", code], restart=False)
        wait_until(lambda: "ready" in (tmp_path / "stuck.log").read_text(), 60)  # the child's files are made
        assert (shm / f"{name}_el").exists()
        la.stop(timeout_s=0.5)
        assert node.proc.returncode in (-signal.SIGUSR1, -signal.SIGTERM)  # killed by the stop (SIGINT ignored)
        assert not (shm / name).exists() and not (shm / f"{name}_el").exists()
    finally:
        la.stop(timeout_s=0.5)
        for n in (name, f"{name}_el"):
            (shm / n).unlink(missing_ok=True)
