"""Fast DDS shared-memory files left behind by killed processes, removed at the next start.

A Fast DDS participant on this host (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST) maps segments
under /dev/shm: ``fastrtps_<16 hex>`` (its own segment), ``fastrtps_port<N>`` (a port shared by
the participants of a domain) and ``fast_datasharing_*``. Each has a lock file beside it
(``<name>_el``, and ``<name>_sl`` for a port) that every process using it keeps locked with
flock(2) while it lives. A process that exits cleanly removes its files; a SIGKILLed one cannot,
and its files stay until reboot (bev_mdo's own fault tests kill nodes on purpose).

The owner's liveness is read from that lock, not from a process id: the kernel drops a flock
when its holder dies, so a lock file nobody holds belongs to no live process, whatever process
ids were reused since. A group (segment, its lock files and, for a port, its ``sem.<port>_mutex``)
is removed only when it belongs to this user, its lock files are older than ``min_age_s`` (a
participant starting right now creates the lock file a moment before it locks it) and every one
of them can be locked here; the locks are held while the files are removed, so a participant
starting meanwhile cannot take the group up half-removed. No rclpy import here.
"""
from __future__ import annotations

import contextlib
import fcntl
import os
import re
import time
from pathlib import Path

SHM_DIR = Path("/dev/shm")
_LOCK_FILE = re.compile(r"^((?:fastrtps_|fast_datasharing_)[A-Za-z0-9_.]+?)_(el|sl)$")


def remove_orphans(shm_dir: str | os.PathLike = SHM_DIR, min_age_s: float = 1.0) -> list[str]:
    """Remove the Fast DDS shared-memory files of this user's processes that are gone (see the
    module doc); returns the names removed. Never raises: a start-up must not fail for this."""
    d = Path(shm_dir)
    try:
        names = os.listdir(d)
    except OSError:
        return []
    groups: dict[str, list[str]] = {}
    for name in names:
        m = _LOCK_FILE.match(name)
        if m:
            groups.setdefault(m.group(1), []).append(name)
    for locks in groups.values():
        locks.sort()
    removed: list[str] = []
    for base, locks in sorted(groups.items()):
        removed += _remove_group(d, base, locks, min_age_s)
    return removed


def _remove_group(d: Path, base: str, locks: list[str], min_age_s: float) -> list[str]:
    now = time.time()
    held = []
    try:
        for name in locks:
            try:
                fd = os.open(d / name, os.O_RDONLY | os.O_NOFOLLOW)
            except OSError:
                return []
            held.append(fd)
            st = os.fstat(fd)
            if st.st_uid != os.getuid() or now - st.st_mtime < min_age_s:
                return []
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:  # held: its owner lives
                return []
        out = []
        mutex = [f"sem.{base}_mutex"] if base.startswith("fastrtps_port") else []
        for name in [base, *mutex, *locks]:
            with contextlib.suppress(FileNotFoundError, PermissionError):
                os.unlink(d / name)
                out.append(name)
        return out
    finally:
        for fd in held:
            os.close(fd)
