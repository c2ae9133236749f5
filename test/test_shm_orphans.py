"""Fast DDS shared-memory files of dead processes are removed at start; a live owner's are kept."""
from __future__ import annotations

import fcntl
import os
import time

from bev_mdo.ros.shm import remove_orphans


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
