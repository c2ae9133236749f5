"""The order of a run's iteration records as they were sent (``Sequence``: every reader of a bag), and the live
recorder's check of each record it is sent (``RecordOrder``: verified first for a signed run, then in order; a
recorder that cannot verify keeps every fresh record of its run and leaves their order to the readers)."""
from __future__ import annotations

from bev_mdo.bag.stored import WINDOW_S


def stamp_ns(header) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def in_run(run_id: str, run: str) -> bool:
    """Whether a record of `run_id` belongs to run `run` (itself or a sub-run ``<run>-...``)."""
    return run_id == run or run_id.startswith(run + "-")


class Sequence:
    """Per-run order of iteration records: each run numbers its records 1, 2, 3, ... (``sequence``, under
    the signature; a synthetic or foreign bag may start at 0), and stamps them when it sends them. A record
    received (recorded) further than ``window_s`` from its stamp is ``expired`` (a record sent again later:
    ``bev-mdo replay`` of an old bag); one whose number was already seen is a ``duplicate`` (of the last) or
    ``from the past`` (a replay of an older record); all are dropped. The stamp is checked first, so a replay
    that reaches the recorder before the run's own records cannot make them look like the past. A number not
    seen yet is kept, below the last too (``late``: recorded after a later record, it fills its gap);
    ``missing`` counts the numbers from 1 up to each run's last that were never seen (0 never is).

    A reader of a bag (the bag is in memory already) holds every number: ``held`` and ``runs`` None. The live
    recorder bounds its memory: at most ``held`` numbers held above the runs' floors in all (past that, the
    lower half of the largest run's gaps is given up: still missing, a record in one of them later is "from the
    past") and ``runs`` run ids tracked (the records of a run beyond them are kept unchecked: ``untracked``)."""

    HELD = 4096  # the live recorder's bounds (RecordOrder): numbers held above the runs' floors in all,
    RUNS = 256   # and run ids tracked (a run and its sub-runs <run>-...)

    def __init__(self, window_s: float = WINDOW_S, held: int | None = None, runs: int | None = None):
        # per run: every number from 1 up to ``floor`` is seen (or given up), ``above`` holds those seen above it
        self.floor: dict[str, int] = {}
        self.above: dict[str, set[int]] = {}
        self.last: dict[str, int] = {}
        self.zero: set[str] = set()  # the runs whose record 0 was seen
        self.held, self.runs, self.size = held, runs, 0  # size: the numbers held in all the ``above`` sets
        self.given_up = 0  # numbers under a floor raised past them unseen (the memory bound): still missing
        self.late = 0
        self.untracked = 0  # records of runs beyond ``runs``, kept unchecked
        self.window_ns = int(window_s * 1e9)

    @property
    def missing(self) -> int:
        return self.given_up + sum(self.last[r] - self.floor[r] - len(self.above[r]) for r in self.last)

    def check(self, run_id: str, sequence: int, stamp_ns: int | None = None,
              received_ns: int | None = None) -> str | None:
        """None to keep the record, else why it is dropped ("expired", "duplicate", "from the past")."""
        if self.expired(stamp_ns, received_ns):
            return "expired"
        if run_id not in self.last:
            if self.runs is not None and len(self.last) >= self.runs:
                self.untracked += 1
                return None
            self.floor[run_id], self.above[run_id], self.last[run_id] = 0, set(), 0
        floor, above, last = self.floor[run_id], self.above[run_id], self.last[run_id]
        seen = run_id in self.zero if sequence == 0 else sequence <= floor or sequence in above
        if seen:
            return "duplicate" if sequence == last else "from the past"
        if sequence < last:
            self.late += 1
        else:
            self.last[run_id] = sequence
        if sequence == 0:
            self.zero.add(run_id)
            return None
        above.add(sequence)
        self.size += 1
        while floor + 1 in above:  # in order, the set stays empty
            floor += 1
            above.discard(floor)
            self.size -= 1
        self.floor[run_id] = floor
        if self.held is not None and self.size > self.held:
            self._give_up(max(self.above, key=lambda r: len(self.above[r])))
        return None

    def expired(self, stamp_ns: int | None, received_ns: int | None) -> bool:
        """Whether a record stamped `stamp_ns` was received further than the window from it (every bev_mdo
        sender stamps its records; an unstamped one cannot be checked)."""
        return bool(stamp_ns) and received_ns is not None and abs(received_ns - stamp_ns) > self.window_ns

    def _give_up(self, run_id: str) -> None:
        """A flood of scattered numbers: the lower half of `run_id`'s gaps are given up (still missing)."""
        floor, above = self.floor[run_id], self.above[run_id]
        cut = sorted(above)[len(above) // 2]
        kept = {n for n in above if n > cut}
        self.given_up += cut - floor - (len(above) - len(kept))
        self.size -= len(above) - len(kept)
        self.floor[run_id], self.above[run_id] = cut, kept


class RecordOrder:
    """The check of the iteration records a recorder is sent (ros/recorder_node), or a replay sends
    (ros/replay): of its own run only (when it has one), authentic for a signed run (``verify``: the run's
    ``Signer.verify_iteration``; checked before the order, so a forged record never takes a number), each
    once and fresh (``Sequence``); ``dropped`` counts the others by reason. ``bounded``: the live recorder's
    memory bounds (``Sequence.HELD``, ``Sequence.RUNS``); a replay reads a whole bag, with none.

    ``ordered`` False: a recorder without the run's key and config (``bev-mdo record`` with no config) keeps
    every fresh record of its run, duplicates and numbers seen before too (``kept``), and holds no number: ordering
    records it cannot verify let a forger who sent a run's numbers first have the genuine records dropped "from
    the past" and choose the count of "missing" ones. The readers verify with the key and keep each run's records
    once and in order (bag/history.py)."""

    def __init__(self, run_id: str = "", window_s: float = WINDOW_S, verify=None, bounded: bool = True,
                 ordered: bool = True):
        self.run_id = run_id
        self.verify = verify
        self.ordered = ordered
        self.kept = 0  # records kept unordered (``ordered`` False)
        self.accepted = 0  # records kept, ordered or not
        self.order = Sequence(window_s, *((Sequence.HELD, Sequence.RUNS) if bounded else ()))
        self.dropped: dict[str, int] = {}

    def keep(self, data, received_ns: int) -> bool:
        from bev_mdo.protocol import WireError, head

        try:
            rec = head(data, "IterationRecord", "sequence")  # the fields up to sequence: no full decode
            if self.run_id and not in_run(rec.run_id, self.run_id):
                why = "of another run"
            elif not self.ordered:
                why = "expired" if self.order.expired(stamp_ns(rec.header), received_ns) else None
                self.kept += why is None
            else:
                why = ((self.verify(data) if self.verify is not None else None)
                       or self.order.check(rec.run_id, int(rec.sequence), stamp_ns(rec.header), received_ns))
        except WireError:
            why = "malformed"
        if why is not None:
            self.dropped[why] = self.dropped.get(why, 0) + 1
        self.accepted += why is None
        return why is None

    def none_note(self) -> str:
        """'' or, for a recorder to which no iteration record came, what may cause it (it ended with "recorded 231
        messages" and nothing else, and history then found no iteration record). Records that came and were
        dropped are ``note``'s."""
        return "" if self.accepted or self.dropped else (
            "; no iteration record came (a pareto run sends none; a coordinator started without -p recorders:=1 may "
            "have sent its records before this recorder matched its topics)")

    def note(self, left_out: str = "dropped") -> str:
        """'' or '; dropped N duplicate, ... iteration record(s); M iteration record(s) missing; ...' (``left_out``:
        the word for what was dropped)."""
        kinds = sorted(self.dropped.items())
        before = [f"{n} {k}" for k, n in kinds if not k.startswith("of ")]  # 'duplicate', 'from the past', ...
        said = [f"{', '.join(before)} iteration record(s)"] if before else []
        said += [f"{n} iteration record(s) {k}" for k, n in kinds if k.startswith("of ")]  # 'of another run'
        parts = [f"{left_out} {' and '.join(said)}"] if said else []
        order = self.order
        parts += [f"{order.missing} iteration record(s) missing"] if order.missing else []
        parts += [f"{order.late} iteration record(s) recorded after a later one (kept)"] if order.late else []
        parts += [f"{self.kept} iteration record(s) kept as received (no key to verify them: the readers verify and "
                  "order them)"] if self.kept else []
        parts += [f"{order.untracked} iteration record(s) of runs beyond the first {order.runs} kept unchecked "
                  "(the recorder's bound)"] if order.untracked else []
        return "".join(f"; {p}" for p in parts)
