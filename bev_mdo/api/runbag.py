"""What a run writes besides the terminal: the in-process bag and the end-of-run answers.

* ``InProcessBag``: with ``--transport inprocess`` the iteration records go straight into a
  rosbag2 MCAP bag (the same ``IterationRecord`` on ``/bev_mdo/iteration`` the recorder node
  writes over ROS, and the run's config in the ``bev_mdo`` metadata record), so ``--bag`` works
  on both transports and ``history``/``report``/``resume`` read either.
* ``ANSWERS_METADATA`` / ``ANSWERS_FILE``: the answers of ``bev_mdo.mdo.active`` at the end of the
  run. In process they are an MCAP metadata record of the bag itself; over ROS (the bag is the
  recorder node's) they are written as ``answers.json`` into the bag directory.
"""
from __future__ import annotations

import contextlib
import os
import sys
import time
import uuid
from pathlib import Path
from typing import Any, Mapping

from bev_mdo import interrupts, jsontext
from bev_mdo.api.errors import InputError
from bev_mdo.bag.history import ANSWERS_FILE, ANSWERS_METADATA


class InProcessBag:
    """Iteration records of an in-process run, written as the recorder node would write them."""

    def __init__(self, bag_dir: Path, config: Mapping[str, Any], run_id: str, transport: str = "inprocess",
                 **metadata_extra: str):
        import yaml

        from bev_mdo.bag.writer import BagWriter
        from bev_mdo.config import plain
        from bev_mdo.protocol.signing import Signer
        from bev_mdo.ros.common import ITERATION_QOS, ITERATION_TOPIC

        self.topic = ITERATION_TOPIC
        self.run_id = run_id
        self.seq = 0
        self.signer = Signer.from_ros(config.get("ros"))  # signed like the coordinator's when a key is configured
        metadata = {"run_id": run_id, "transport": transport,
                    "config_yaml": yaml.safe_dump(plain(dict(config)), sort_keys=False), **metadata_extra}
        self.writer = None
        self.failed = None  # why the bag could no longer be written (e.g. a full disk): the run goes on without it
        try:
            with interrupts.deferred():  # a signal while the bag is started: it is closed before the run stops
                self.writer = BagWriter(bag_dir, metadata=metadata)
                self.writer.add_topic(ITERATION_TOPIC, "bev_mdo_msgs/msg/IterationRecord", ITERATION_QOS)
        except BaseException:
            if self.writer is not None:
                self.close()
            raise

    def __call__(self, rec: Mapping[str, Any]) -> None:
        if self.failed:
            return
        from rclpy.serialization import serialize_message

        from bev_mdo import protocol
        from bev_mdo.ros.common import stamp
        from bev_mdo_msgs.msg import IterationRecord

        msg = IterationRecord()
        stamp(msg.header)
        self.seq += 1
        protocol.fill_iteration_record(msg, rec, self.run_id, self.seq)
        t = time.time_ns()
        data = serialize_message(msg) if self.signer is None else self.signer.sign_iteration(msg)
        try:
            with interrupts.deferred():  # a record is written whole or not at all
                self.writer.write(self.topic, data, t, t, self.seq)
                self.writer.flush()  # one chunk per record: even a SIGKILL keeps every finished iteration
        except OSError as exc:  # like a recorder that died over ROS: the run ends with its result, exit status 3
            self.writer.abandon()
            bag = self.writer.bag_dir
            self.failed = (f"writing the bag {bag} failed at iteration {rec['iteration']} ({exc.strerror or exc}); it "
                           f"holds the iterations before, and `bev-mdo bag repair {bag}` makes it whole")

    def close(self, answers: Mapping[str, Any] | None = None) -> None:
        """Finish the bag (summary, metadata.yaml); idempotent. Called at the end of the run with the
        answers, and on any interruption (SIGINT, SIGTERM, an exception) without them."""
        if self.failed:  # abandoned when its write failed
            return
        with interrupts.deferred():
            if answers is not None and not self.writer.closed:
                text = jsontext.dumps(answers, None)
                sig = {"answers_signature": self.signer.sign_answers(text)} if self.signer is not None else {}
                self.writer._mcap.add_metadata(ANSWERS_METADATA, {"answers_json": text, **sig})
            self.writer.close()


def answers(config: Mapping[str, Any], result: Mapping[str, Any]) -> dict:
    """The end-of-run answers (``bev_mdo.mdo.active``) for a run result dict, with the same time budget
    per discipline call as the run had (a hung user discipline must not hang the answers)."""
    from bev_mdo.config import RunConfig
    from bev_mdo.mdo.active import answers_for
    from bev_mdo.mdo.units import run_units

    values = {k: c["value"] for k, c in result.get("constraints", {}).items()}
    values.update({k: v for k, v in result.get("outputs", {}).items() if k not in values})
    config = RunConfig.of(config)
    discs = config.timed_disciplines()
    ans = answers_for(config.settings, result["design"], values, disciplines=discs, units=run_units(discs))
    lines = inconsistent_lines(result)
    if lines:  # IDF ended where its couplings are not what their disciplines give: say so first
        ans["feasible"], ans["lines"] = False, [*lines, *ans["lines"]]
    return ans


def inconsistent_lines(result: Mapping[str, Any]) -> list[str]:
    """IDF's consistency equalities that the result breaks beyond the feasibility tolerance, one line each, and
    what that means for its numbers: the run's objective and largest violation are at the optimiser's coupling
    values, the outputs shown are the design analysed through (an MDA). [] when consistent, or not IDF."""
    tol = float(result.get("feasibility_tolerance") or 0.0)
    broken = [e for e in (result.get("first_order") or {}).get("equalities", []) if abs(e["value"]) > tol]
    if not broken:
        return []
    obj, analysed = result.get("objective_name"), (result.get("outputs") or {}).get(result.get("objective_name"))
    lines = [f"not consistent: {e['name'].removesuffix(' consistency')}: the optimiser's coupling value is not what "
             f"its discipline computes there (residual {abs(e['value']):.3g}, normalised)" for e in broken]
    held, analysed = (f"{v:.6g}" if v is not None else "nan" for v in (result.get("objective"), analysed))
    if held != analysed:  # the run's objective is not the outputs' (else the lines above say it all)
        lines.append(f"  so the run's {obj} {held} and its largest violation are at the optimiser's coupling values; "
                     f"the design analysed through (the outputs shown) gives {obj} {analysed}")
    return lines


class RecordTally:
    """The run's iteration callback, counting what the run sent to its bag: the records, the last one's
    number and where each design was recorded (first and last), so the end-of-run record can say how
    many records the bag should hold and which one is the result (``finish``); a bag whose recorder
    died holds fewer (bag/history.missing_tail)."""

    def __init__(self, show):
        self.show = show
        self.records = 0
        self.last_iteration: int | None = None
        self.at: dict[tuple, list[int]] = {}  # design -> [first, last] iteration recorded there

    def __call__(self, rec: Mapping[str, Any]) -> None:
        self.records += 1
        k = int(rec["iteration"])
        self.last_iteration = k
        self.at.setdefault(tuple(sorted(rec["design"].items())), [k, k])[1] = k
        self.show(rec)

    def run_record(self, result: Mapping[str, Any], stopped_early: bool = False) -> dict:
        """What the answers store of the run beside its ``result_design``: its record count, last and
        result iteration (the first record at the result for a run stopped early, as the driver picks it,
        else the last), the result's objective, violation and feasibility, and the run's MDA total."""
        seen = self.at.get(tuple(sorted((result.get("design") or {}).items())))
        return {"records": self.records, "last_iteration": self.last_iteration,
                "result_iteration": None if seen is None else seen[0 if stopped_early else 1],
                "result_objective": result.get("objective"), "result_max_violation": result.get("max_violation"),
                "result_feasible": result.get("feasible"), "mda_evaluations": result.get("mda_evaluations")}


def finish(config: Mapping[str, Any], result: dict, extra: dict, tally: RecordTally | None = None) -> None:
    """Add ``result["active"]`` and store it with the run's bag (closing an in-process bag; one whose writing
    failed adds ``recorder_failed`` to ``extra``), with what ``tally`` counted of the run's records."""
    inproc = extra.get("_bag_writer")
    result["active"] = answers(config, result)  # (a signal or failure here: api/optimize.run closes an in-process bag)
    ans = {**result["active"], "result_design": result.get("design")}  # the report names the run's result by it
    if tally is not None:  # what the bag should hold: a dead recorder's bag holds less (bag/history.missing_tail)
        ans.update(tally.run_record(result, bool(extra.get("unresponsive_disciplines"))))
    if extra.get("unresponsive_disciplines"):  # how the run ended, for the report (bag/history.run_ending)
        ans.update(unresponsive_disciplines=list(extra["unresponsive_disciplines"]), stopped=result.get("stopped", ""))
    if inproc is not None:
        inproc.close(ans)
        if inproc.failed:
            extra["recorder_failed"] = inproc.failed
    elif extra.get("bag"):  # over ROS: answers.json beside the recorder's bag, signed with the run's key
        from bev_mdo.bag.signing import run_key_path
        from bev_mdo.protocol.signing import Signer, read_key

        path = Path(extra["bag"]) / ANSWERS_FILE
        path.parent.mkdir(parents=True, exist_ok=True)
        text = jsontext.dumps(ans) + "\n"
        path.write_text(text, encoding="utf-8")
        key = run_key_path(extra["bag"])  # the per-run key, or a link to the configured one (bag.signing)
        if key.is_file():
            path.with_name(ANSWERS_FILE + ".sig").write_text(Signer(read_key(key)).sign_answers(text) + "\n")
    if extra.get("bag") and not extra.get("recorder_failed"):  # said if a signal comes after the result
        interrupts.note_done(f"the bag {extra['bag']} is complete (bev-mdo report {extra['bag']}; "
                             f"bev-mdo history {extra['bag']})")


def interrupted_note(bag, kind: str = "iteration") -> str:
    """What an interrupted run's bag holds, for the line after ``bev-mdo: interrupted``: its iteration
    records (``optimize``) or its Pareto fronts (``kind="front"``, ``pareto``)."""
    from bev_mdo.bag.reader import open_bag

    if kind == "front":
        from bev_mdo.ros.pareto_publisher import PARETO_TOPIC as topic
        noun, holds = "Pareto front", "one per finished generation"
    else:
        from bev_mdo.bag.history import ITERATION_TOPIC as topic
        noun, holds = "iteration record", (f"every finished iteration (bev-mdo history {bag}; bev-mdo resume {bag} "
                                           "goes on from the last)")
    if not any(Path(bag).glob("*.mcap")):  # stopped before the recorder opened its file: no bag to name
        logs = Path(bag) / "logs"
        return (f"no bag was written (stopped before the recorder started)"
                + (f"; the nodes' logs are in {logs}" if logs.is_dir() else ""))
    try:
        records = sum(1 for _ in open_bag(bag).messages([topic]))
    except Exception:  # noqa: BLE001 - no file yet (stopped before the recorder wrote one), or unreadable
        records = 0
    if not records:
        return f"bag {bag}: no {noun} (stopped before the first)"
    return f"bag {bag}: {records} {noun}{'' if records == 1 else 's'}, {holds}"


def in_process_bag(config: Mapping[str, Any], opts, show, closing: contextlib.ExitStack):
    """(bag path or None, writer or None, iteration callback) for an in-process run: a bag only with --bag. The
    writer is closed as ``closing`` ends (the run's, whatever ends it), from the moment it exists."""
    if opts.no_record or not opts.bag:
        return None, None, show
    # as over ROS (the writer refused only a bag in the folder itself); claimed until the bag's file exists
    with claim_new_bag(Path(opts.bag), opts.bag_flag), interrupts.deferred():  # no signal between open and closing
        writer = InProcessBag(Path(opts.bag), config, uuid.uuid4().hex[:16])
        closing.callback(writer.close)
        interrupts.note_bag(lambda: interrupted_note(opts.bag))  # a signal from now on: what the bag holds

    def callback(rec):
        writer(rec)
        show(rec)

    return str(opts.bag), writer, callback


def check_new_bag(bag: Path, what: str, out: Path | None = None) -> None:
    """A bag may be written to `bag`: InputError (exit 2) naming it if a bag, a file or another run's end-of-run
    record are there (kept beside the new run's, they would be read as its own). ``out``: the output
    folder the user named (sweep's, pareto's --out), whose bag/ `bag` is: checked first (its readers take a bag
    or a run's files in it), and the folder the line names."""
    bag = Path(bag)
    inner = in_use(bag)
    why = inner if out is None else in_use(Path(out), "folder") or (inner and f"its {bag.name}/ {inner}")
    if why:
        raise InputError(f"{what} {bag if out is None else out}: {why}")


def in_use(folder: Path, kind: str = "bag directory") -> str:
    """'' if a run may write into `folder` (a ``kind``), else why not (one phrase). A folder whose only run's file is
    the logs/ of a run that wrote no bag (stopped before its recorder started, or --no-record) may: the claim moves
    them aside first (set_aside_logs)."""
    if folder.exists() and not folder.is_dir():
        return f"is a file, not a {kind}"
    blocking = next((p for p in folder.parents if p.exists() and not p.is_dir()), None)
    if blocking is not None:
        return f"{blocking} is a file, not a folder"
    from bev_mdo.bag.reader import holds_bag

    if holds_bag(folder):
        return "a bag already exists there; choose a new directory"
    left, odd = [], []
    for name, is_dir in (("logs", True), (ANSWERS_FILE, False)):  # what a run writes there: a folder, a file
        p = folder / name
        if p.exists() and p.is_dir() != is_dir:  # not a run's: this run could not write its own there
            odd.append(f"a {'file' if is_dir else 'folder'} named {name} (a run writes its {name}{'/' * is_dir} there)")
        elif p.is_file() or p.is_dir() and any(p.iterdir()):
            left.append(name + "/" * is_dir)
    if left and left != ["logs/"]:  # a run's end-of-run record: its bag is gone or elsewhere, it would be read as ours
        return f"holds another run's {' and '.join(left)}; choose a new directory"
    if odd:
        return f"holds {' and '.join(odd)}; choose a new directory"
    inner = sorted(d.name + "/" for d in (folder.iterdir() if folder.is_dir() else ()) if d.is_dir() and holds_bag(d))
    if len(inner) == 1:  # a run's output folder (sweep's, pareto's): its readers would take the new bag
        return f"a run's output folder, its bag in {inner[0]}; choose a new directory"
    if inner:  # a folder of runs (bags/): a bag beside theirs would make it one run's output folder
        return f"holds {len(inner)} runs' bags ({', '.join(inner[:3])}{', ...' * (len(inner) > 3)}); choose a new directory"
    return ""


CLAIM_FILE = ".bev_mdo_claim"  # in a bag directory while a run claims it (BagClaim)


class BagClaim:
    """One run's claim of a new bag directory: an exclusive ``flock`` on ``<bag>/.bev_mdo_claim``, taken
    where the run checks that no bag is there and held until the run has its bag. Of two runs given the same
    directory at once one claims it; the other is refused before it writes anything (logs, key, nodes),
    as if the bag were there. The kernel drops the lock of a process that dies, so a run killed before its
    bag existed does not block a re-run. ``release()`` (idempotent; also on leaving a ``with``) removes the
    file and the folders the claim made that are still empty."""

    def __init__(self, bag: Path):
        self.bag = Path(bag)
        self.path = self.bag / CLAIM_FILE
        self.made = []  # the folders this claim creates, deepest first
        d = self.bag
        while not d.exists() and d != d.parent:
            self.made.append(d)
            d = d.parent
        self._fd = None

    def acquire(self) -> bool:
        """Take the claim; False if another run holds it. OSError if the folder cannot be made."""
        self.bag.mkdir(parents=True, exist_ok=True)
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o600)
            try:
                import fcntl

                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                os.close(fd)
                return False
            try:
                current = os.path.samestat(os.fstat(fd), os.stat(self.path))
            except FileNotFoundError:
                current = False
            if current:
                self._fd = fd
                return True
            os.close(fd)  # its holder released (removed) the file we opened: claim the one there now

    def release(self) -> None:
        fd, self._fd = self._fd, None
        if fd is not None:
            with contextlib.suppress(OSError):
                os.unlink(self.path)  # while still locked: nobody else holds the file it names
            os.close(fd)
        for d in self.made:
            try:
                d.rmdir()
            except OSError:  # not empty (the bag, the run's logs), or gone
                break

    def __enter__(self) -> "BagClaim":
        return self

    def __exit__(self, *exc) -> None:
        self.release()


def claim_new_bag(bag: Path, what: str, out: Path | None = None) -> BagClaim:
    """``check_new_bag`` (of ``out`` too, when given), then the claim of ``bag`` for this run (BagClaim, to release
    once the run has its bag or ended): InputError (exit 2) if another run claimed it first (it is being written),
    or wrote its bag between the check and the claim."""
    bag = Path(bag)
    check_new_bag(bag, what, out)  # refused here, nothing is touched
    claim = BagClaim(bag)
    try:
        if not claim.acquire():
            raise InputError(f"{what} {bag if out is None else out}: is being written by another run; choose a new "
                             "directory")
        check_new_bag(bag, what, out)  # claimed: a bag written meanwhile is refused, and none can start now
        for folder in dict.fromkeys([bag] if out is None else [Path(out), bag]):
            set_aside_logs(folder, what)
    except OSError as exc:
        claim.release()
        raise InputError(f"{what} {bag if out is None else out}: cannot create the bag directory "
                         f"({exc.strerror or exc})") from None
    except BaseException:
        claim.release()
        raise
    return claim


def set_aside_logs(folder: Path, what: str) -> None:
    """Move the logs/ that a run which wrote no bag left in `folder` (in_use lets such a folder be reused) to the
    first free ``logs.N/``, said in one line on stderr: the new run's logs/ holds its own alone (they were
    appended to the old run's files of the same name). Called under the claim: no live run writes there."""
    logs = folder / "logs"
    if not logs.is_dir() or not any(logs.iterdir()):
        return
    n = next(i for i in range(1, 10**6) if not (folder / f"logs.{i}").exists())
    try:
        logs.rename(folder / f"logs.{n}")
    except OSError as exc:  # said as what failed, not as the bag directory (claim_new_bag's fallback)
        raise InputError(f"{what} {folder}: cannot move the logs/ of an earlier run that wrote no bag to "
                         f"logs.{n}/ ({exc.strerror or exc}); move or remove it") from None
    print(f"{what} {folder}: the logs/ of an earlier run that wrote no bag moved to logs.{n}/", file=sys.stderr,
          flush=True)
