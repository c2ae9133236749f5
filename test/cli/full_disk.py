"""`bev-mdo` on a disk that fills up: ``python full_disk.py N optimize CONFIG --transport inprocess --bag B`` makes
every write to the bag file fail with ENOSPC (no space left on device), as a full disk's writes do, once N
iteration records are in it (test_interrupt_bag.py)."""
from __future__ import annotations

import errno
import sys


class FillingDisk:
    """A file whose writes fail once ``full`` is set."""

    def __init__(self, f):
        self.f, self.full = f, False

    def _check(self) -> None:
        if self.full:
            raise OSError(errno.ENOSPC, "No space left on device")

    def write(self, data):
        self._check()
        return self.f.write(data)

    def flush(self):
        self._check()
        return self.f.flush()

    def __getattr__(self, name):
        return getattr(self.f, name)


if __name__ == "__main__":
    from bev_mdo.bag import writer as bag_writer
    from bev_mdo.cli import main

    records = int(sys.argv.pop(1))
    bag_writer.open = lambda path, mode: FillingDisk(open(path, mode))  # the bag file only (writer.py's open)
    write = bag_writer.BagWriter.write

    def write_until_full(self, *args, **kwargs):
        self._stream.full = self.message_count >= records  # the record after the N-th finds the disk full
        return write(self, *args, **kwargs)

    bag_writer.BagWriter.write = write_until_full
    sys.exit(main())
