"""SIGINT and SIGTERM that third-party code cannot lose.

The CLI turns both signals into exceptions raised in the main thread (KeyboardInterrupt, and
``Terminated`` for SIGTERM), so every ``finally`` runs and a run's bag is closed. A library that wraps
a line in a bare ``except:`` (pymoo does, around a hash and a dtype cast it runs per individual)
swallows the exception when the signal lands there, and the run goes on; so does a ctypes callback (numba's
compiler, through llvmlite: "Exception ignored on calling ctypes callback"). So the handler also keeps
the signal as pending, and the engine's loops (and calibrate's fit) call ``check()`` once per batch: a
swallowed signal is raised again at the next batch, and at the latest when the command returns, which then
ends as interrupted (the CLI; a command whose normal end is a signal, ``record`` and ``node``, calls ``clear``).
Whatever exception surfaces once a signal fired (compiled code's "SystemError: ... returned a result with an
exception set", an import cut short: "ImportError: initialization failed") is the signal's: the CLI ends with
its ``interrupted`` line, not with an error.

What the CLI says when a signal stops it (``interrupted_lines``) follows what is on disk and on screen, not
where in the code the signal landed: once a run has its bag (``note_bag``) the line names it and what it
holds; once the result is stored with it (``note_done``), that the bag is complete and whether the result
was printed (``printing``). Once the ``bev-mdo`` process has written its output (``work_done``), there is
nothing left to unwind: a signal then ends the process at once, during whatever teardown remains (a hung
one included), with one line saying that the result was written and what else is complete, exit status
130 or 143 as for any other Ctrl-C or SIGTERM.

A node executable (ros/run.py) runs its main through ``run_main``: a signal it raises on ends it with one line,
``<node>: interrupted``, status 130 or 143; the recorder closes its bag inside ``deferred()`` first.
"""
from __future__ import annotations

import contextlib
import os
import signal
import sys


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised into the main thread like SIGINT's KeyboardInterrupt; exit status 143."""


_pending: type[BaseException] | None = None
_deferring = 0  # > 0 inside deferred(): a signal is kept and raised at the block's end
_done_status: int | None = None  # work_done's exit status: a signal now ends the process (_end_now)
_bag_note = None  # () -> str: what the run's bag holds (note_bag), read when a signal stops the run
_done_notes: list[str] = []  # what is complete besides the printed result (note_done)
_printing = False  # the command has begun writing its result (printing)
_taken: list[type[BaseException]] = []  # every signal taken since install (held: which came inside its block)


def _handler(exc: type[BaseException]):
    def handle(signum, frame) -> None:
        global _pending
        if _done_status is not None:
            _end_now(exc)
        _pending = exc
        _taken.append(exc)
        if not _deferring:
            raise exc()

    return handle


def new_run() -> None:
    """A run begins (a command: ``install``; a Python API run): what an earlier run in this process noted of its
    bag and its result (note_bag, note_done, printing) is not this one's."""
    global _bag_note, _printing
    _bag_note, _printing = None, False
    _done_notes.clear()


def work_done(status: int) -> None:
    """The ``bev-mdo`` process has written its output (exit status ``status``); what remains is its teardown.
    From now on SIGINT or SIGTERM end the process at once (``_end_now``). For the process itself only: a
    library caller of the CLI would be ended with it."""
    global _done_status
    _done_status = status


def note_bag(describe) -> None:
    """The run has its bag from now on: a signal that stops it before its result is stored ends with
    ``bev-mdo: interrupted`` and ``bev-mdo: <describe()>``, what the bag holds then (api/runbag.interrupted_note)."""
    global _bag_note
    _bag_note = describe


def note_done(note: str) -> None:
    """Something complete besides the printed result (e.g. "the bag B is complete"): from now on a signal's
    line says it, whether the result was being printed, or not yet, or written already."""
    _done_notes.append(note)


def printing() -> None:
    """The command begins writing its result: a signal from now on came "while the result was printed"
    (before, after ``note_done``: "before the result was printed")."""
    global _printing
    _printing = True


def interrupted_lines(exc: BaseException) -> list[str]:
    """The lines on stderr of a command that a signal stopped (``exc``: KeyboardInterrupt, or Terminated)."""
    what = "bev-mdo: terminated (SIGTERM)" if isinstance(exc, Terminated) else "bev-mdo: interrupted"
    if _done_notes:  # the result is stored (e.g. with its bag)
        return ["; ".join([f"{what} {'while' if _printing else 'before'} the result was printed", *_done_notes])]
    return [what, *([f"bev-mdo: {_bag_note()}"] if _bag_note is not None else [])]


def _end_now(exc: type[BaseException]) -> None:
    """A signal after the work: one line on stderr, then the process ends without its teardown (exit status
    143 for SIGTERM, else 130). Nothing is lost: the output is written and flushed and any bag closed; only
    the shutdown that remained, which a signal must be able to cut short, is skipped."""
    terminated = issubclass(exc, Terminated)
    what = "terminated (SIGTERM)" if terminated else "interrupted"
    if _done_status in (130, 143):  # the work itself was stopped by a signal, and said so
        line = f"bev-mdo: {what} again while ending"
    else:
        line = "; ".join([f"bev-mdo: {what} after the result was written", *_done_notes])
    with contextlib.suppress(Exception):  # a closed pipe, or a write the signal cut into
        sys.stdout.flush()
    with contextlib.suppress(OSError):
        os.write(2, (line + "\n").encode())
    os._exit(143 if terminated else 130)


@contextlib.contextmanager
def deferred():
    """A block that a signal does not cut in two (a bag record written halfway leaves a file no reader can
    open past it): SIGINT or SIGTERM arriving inside is raised when the block ends."""
    global _deferring
    _deferring += 1
    try:
        yield
    finally:
        _deferring -= 1
        if not _deferring and _pending is not None:
            raise _pending()


@contextlib.contextmanager
def held():
    """A teardown that a signal does not cut short (Launcher.stop: a node left before its SIGKILL runs on,
    orphaned): SIGINT or SIGTERM arriving inside is raised when the block ends; one taken before it (the
    Ctrl-C that started the teardown) is not raised again."""
    global _deferring
    before = len(_taken)
    _deferring += 1
    try:
        yield
    finally:
        _deferring -= 1
        if not _deferring and len(_taken) > before:
            raise _taken[-1]()


def install(sigint_ignored_too: bool = False) -> dict:
    """Handlers for SIGTERM and (unless it is ignored, as in a shell's background job, and not
    ``sigint_ignored_too``) SIGINT; returns the previous handlers for ``restore``. Main thread only."""
    global _pending, _done_status
    _pending, _done_status = None, None
    new_run()
    _taken.clear()
    previous = {signal.SIGTERM: signal.signal(signal.SIGTERM, _handler(Terminated))}
    if sigint_ignored_too or signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        previous[signal.SIGINT] = signal.signal(signal.SIGINT, _handler(KeyboardInterrupt))
    previous["unraisablehook"], sys.unraisablehook = sys.unraisablehook, _quiet_when_pending(sys.unraisablehook)
    return previous


def _quiet_when_pending(hook):
    """``sys.unraisablehook`` silent once a signal fired: the signal's exception that a callback swallowed
    ("Exception ignored on calling ctypes callback function": numba's compiler, through llvmlite), and what objects
    the signal left half-made say as they are collected (llvmlite's ``ObjectRef.__del__``: "AttributeError: ... no
    attribute '_as_parameter_'"), are no traceback: the signal's one line ends the command. Before, ``hook``."""
    def unraisable(u) -> None:
        if _pending is None:
            hook(u)

    return unraisable


def restore(previous: dict) -> None:
    """The handlers ``install`` replaced, back; a signal they took is forgotten (a later run in this process,
    without handlers, would raise it again at its first ``check``)."""
    global _pending
    for signum, handler in previous.items():
        if signum == "unraisablehook":
            sys.unraisablehook = handler
        else:
            signal.signal(signum, handler)
    _pending = None
    _taken.clear()


def clear() -> None:
    """The signal taken was the command's normal end (``record``: the end of the recording, ``node``: of the
    node's service, both exit 0), not an interruption to raise again."""
    global _pending
    _pending = None


def pending() -> type[BaseException] | None:
    """The exception of the signal taken since ``install`` (KeyboardInterrupt, or Terminated), or None."""
    return _pending


def check() -> None:
    """Raise again a signal whose exception was swallowed on the way (a no-op otherwise)."""
    if _pending is not None:
        raise _pending()


def run_main(name: str, main, *args) -> int:
    """``main(*args)``'s exit status, with the handlers installed (both signals raise in the main thread; rclpy's
    handlers, installed later, pass them on): a SIGINT or SIGTERM it raises on ends it with one line on stderr,
    ``<name>: interrupted``, and status 130 (143 for SIGTERM). For a node executable (ros/run.py), which a script
    starts as a `&` job with SIGINT ignored: `kill -INT` ends it all the same, as it ends any rclpy node (the
    recorder went on recording, and the coordinator, stopped by rclpy's handler alone, raised from its publisher)."""
    install(sigint_ignored_too=True)
    try:
        return main(*args)
    except BaseException as exc:
        if _pending is None and (said := _refused_ros_args(exc)):  # a usage mistake: one line, status 2
            print(f"{name}: error: {said}", file=sys.stderr, flush=True)
            return 2
        if _pending is None and not _shut_down_by_rclpy(exc):
            raise
        print(f"{name}: interrupted", file=sys.stderr, flush=True)
        return 143 if _pending is not None and issubclass(_pending, Terminated) else 130


def _refused_ros_args(exc: BaseException) -> str:
    """rcl's refusal of malformed ``--ros-args`` (``-p config=x.yaml``, ``-p instance:=``, a params file that is not
    a mapping, ``--log-level bogus``), said in one line with rcl's reason and without its source locations; ''
    for anything else (it was a traceback and status 1)."""
    import re

    text = str(exc)
    if type(exc).__name__ != "RCLError" or not text.startswith("failed to initialize rcl: "):
        return ""
    said = re.sub(r"(, at /\S+)+$", "", text.removeprefix("failed to initialize rcl: ")).replace(". Error: error not set", "")
    hint = (" (a parameter is -p name:=value, e.g. -p config:=my.yaml; an empty text is -p \"name:=''\")"
            if "parameter override" in said or "-p flag" in said else " (a node name is -r __node:=NAME)"
            if "remap rule" in said else "")
    return f"--ros-args: {said}{hint}"


def _shut_down_by_rclpy(exc: BaseException) -> bool:
    """rclpy's own handler shut the context down on a signal Python ignores (a `&` job's SIGINT): the executor
    raises ExternalShutdownException or, caught while it makes its wait set, RCLError "... rcl_shutdown() was
    called" (the node shuts its context down only after its main has returned or raised)."""
    name = type(exc).__name__
    return name == "ExternalShutdownException" or (name == "RCLError" and any(
        said in str(exc) for said in ("rcl_shutdown() was called", "context is invalid")))
