"""The ``bev-mdo`` command line. One module per subcommand, each with ``register(subparsers)``.

The parser is built from the light table :data:`SUBCOMMANDS`: only the module of the chosen
subcommand is imported (so ``bev-mdo validate`` does not load rclpy, scipy or matplotlib for the
others); the rest are listed by name and help. A subcommand module that fails to import raises.

A user mistake (bad config, bad value, bad file) prints one line on stderr and exits 2.
"""
from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import sys
import threading
import traceback
import warnings
from collections.abc import Mapping
from pathlib import Path

from bev_mdo import interrupts
from bev_mdo.interrupts import Terminated  # SIGTERM as an exception: every finally runs, exit 143
from bev_mdo.stacks import (STARTUP_GAVE_UP_STATUS, StartupGaveUp, bound_exit, defer_teardowns, dump_stacks_on_sigusr1,
                            end_process)

# command -> (module in bev_mdo.cli, help), in the order --help lists them. The module's register() adds
# the command's parser, which gets this help (_Commands; test/cli/test_cli_table.py checks it).
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "optimize": ("optimize", "run the distributed MDF/IDF optimisation (the main job)"),
    "evaluate": ("evaluate", "evaluate one design through all disciplines"),
    "node": ("node", "run one discipline node (vehicle_mass, energy, range, acceleration, motor_speed, cost, "
                     "or any discipline named in the config)"),
    "record": ("record", "record bev_mdo topics to a rosbag2 MCAP bag"),
    "replay": ("replay", "publish the messages of a recorded bag again"),
    "history": ("history", "print the optimisation history of a bag"),
    "report": ("report", "plots and a markdown summary of a recorded run"),
    "resume": ("resume", "restart an optimisation from the last iterate recorded in a bag"),
    "bag": ("bag", "inspect or repair a recorded bag"),
    "sensitivity": ("sensitivity", "normalised 1st/2nd-order sensitivities at a design, or global "
                                   "Sobol'/Morris indices over the bounds"),
    "pareto": ("pareto", "NSGA-II Pareto front of any problem with two or more objectives "
                         "(--topology / --all-topologies: the BEV topology study, thesis ch.4)"),
    "sweep": ("sweep", "a design of experiments, grid or list of designs as one batch: CSV, PNG, bag"),
    "compare": ("sweep", "two or more designs side by side with their differences"),
    "graph": ("graph", "the coupling graph as an N² chart (PNG) and Graphviz DOT text"),
    "validate": ("validate", "predicted vs measured energy over a fleet of tested vehicles"),
    "calibrate": ("calibrate", "fit a model's fleet-wide parameters to a fleet of measured cars, cross-validated "
                               "by family and by make"),
    "check-partials": ("check_partials", "compare analytic partial derivatives with finite differences"),
    "check-totals": ("check_totals", "compare the optimiser's total derivatives with finite differences"),
    "status": ("status", "list the live discipline instances on the ROS domain (host, throughput)"),
}


def figure_format(path) -> str | None:
    """The ``format`` for ``fig.savefig(path)`` of a ``--png FILE`` option, so that exactly ``path`` is
    written (matplotlib would append ``.png`` to a name without an extension): PNG for such a name,
    else None (the extension's format); ValueError for a directory or standard output (a binary image
    among the command's text; /dev/stdout went to stderr: is_stdout). Commands call it on their
    arguments first, so that such a path is refused before anything is computed."""
    if is_stdout(path) or _terminal(path):
        raise ValueError(f"--png {path}: a PNG is binary, not written to "
                         f"{'standard output' if is_stdout(path) else 'standard error or a terminal'}; give a file "
                         "name, e.g. plot.png")
    p = Path(path)
    if p.is_dir():
        raise ValueError(f"cannot write {path}: it is a directory (give a file name, e.g. {p / 'plot.png'})")
    return None if p.suffix else "png"


def energy_cycle_label(cfg) -> str:
    """What a figure or table names as the cycle of a result: the one the energy discipline's energy per km is
    computed on ('cycle nedc'; its option ``cycle`` before the config's), or the distance-weighted mix of its
    option ``cycle_weights`` ('cycle mix 55 % epa_udds + 45 % epa_hwfet'), not the config's cycle when that only
    sets the top speed; the config's cycle without an energy discipline; '' without a cycle."""
    from bev_mdo.models.cycles import is_csv_cycle

    def shown(name) -> str:  # a CSV trace by its file name, not the absolute path the config resolves it to
        return Path(name).name if isinstance(name, str) and is_csv_cycle(name) else str(name)

    cyc = (cfg or {}).get("cycle")
    name = cyc.get("name", "") if isinstance(cyc, Mapping) else str(cyc or "")
    for e in (cfg or {}).get("disciplines") or []:
        opts = e.get("options") if isinstance(e, Mapping) and e.get("name") == "energy" and not e.get("class") else None
        if isinstance(opts, Mapping) and isinstance(opts.get("cycle_weights"), Mapping) and opts["cycle_weights"]:
            return "cycle mix " + " + ".join(f"{100 * float(w):.3g} % {shown(k)}" for k, w in opts["cycle_weights"].items())
        if isinstance(opts, Mapping) and opts.get("cycle"):
            name = opts["cycle"]
    return f"cycle {shown(name)}" if name else ""


def _terminal(path) -> bool:
    """A name of descriptor 2 or of a terminal (/dev/tty, /dev/pts/N, /dev/console), by its name only (a
    device is not opened to ask): ``--png /dev/stderr`` wrote the image's bytes to the terminal."""
    return str(path) in ("/dev/stderr", "/dev/fd/2", "/proc/self/fd/2") or os.path.realpath(path).startswith(
        ("/dev/tty", "/dev/pts/", "/dev/console"))


def save_figure(fig, path, dpi: int = 110) -> None:
    """Write the figure of a ``--png FILE`` option to exactly ``path``; a path that cannot be written is
    one ValueError naming it and why."""
    try:
        fig.savefig(path, dpi=dpi, format=figure_format(path))
    except OSError as exc:
        raise cannot_write(path, exc) from None


def is_stdout(path) -> bool:
    """``-`` or a name of descriptor 1 (``/dev/stdout``): the output goes to ``sys.stdout``. Opened by
    name, /dev/stdout is descriptor 1, which bev-mdo points at stderr while it runs
    (native_output_to_stderr): ``--csv /dev/stdout`` wrote the CSV to stderr."""
    return str(path) in ("-", "/dev/stdout", "/dev/fd/1", "/proc/self/fd/1")


def write_text_file(path, text: str) -> None:
    """Write an output file the user named (``--csv FILE``, ``--dot FILE``); a path that cannot be
    written is one ValueError naming it and why (not the raw ``[Errno 2] ...``)."""
    try:
        with open(path, "w", encoding="utf-8") as f:
            f.write(text)
    except OSError as exc:
        raise cannot_write(path, exc) from None


def cannot_write(path, exc: OSError) -> ValueError:
    """One line for an output file that could not be written: its name and the reason."""
    folder = Path(path).parent
    if isinstance(exc, FileNotFoundError) and not folder.is_dir():
        reason = f"the folder {folder} does not exist"
    elif isinstance(exc, IsADirectoryError):
        reason = "it is a directory (give a file name)"
    else:
        reason = exc.strerror or str(exc)
    return ValueError(f"cannot write {path}: {reason}")


def _chosen(argv: list[str]) -> str | None:
    """The subcommand named in ``argv`` (its first word that is not an option), if it is one."""
    for word in argv:
        if word == "--":
            return None
        if not word.startswith("-"):
            return word if word in SUBCOMMANDS else None
    return None


class _Commands(argparse._SubParsersAction):  # argparse's class for add_subparsers(action=...)
    """bev-mdo's subcommands: each one's help is its line of SUBCOMMANDS, written there alone."""

    def add_parser(self, name, **kwargs):
        return super().add_parser(name, **{"help": SUBCOMMANDS[name][1], **kwargs})


class _Parser(argparse.ArgumentParser):
    """A usage mistake is one line on stderr, as every other user mistake (exit 2), naming --help."""
    given: list[str] = []  # the words this parser was given (error: which options they used)

    def parse_known_args(self, args=None, namespace=None):
        self.given = list(sys.argv[1:] if args is None else args)
        return super().parse_known_args(args, namespace)

    def chosen(self, args, extra: list[str], words: list[str]) -> "_Parser":
        """The parser the ``extra`` words were given to: that of the innermost subcommand ``args`` chose (`bev-mdo
        bag info BAG --bogus`: bag info's) unless one of them came before its name (`bev-mdo bag --bogus info`)."""
        act = next((a for a in self._actions if isinstance(a, argparse._SubParsersAction)), None)
        name = getattr(args, act.dest, None) if act else None
        if name not in getattr(act, "choices", {}) or name not in words or set(extra) & set(words[:words.index(name)]):
            return self
        return act.choices[name].chosen(args, extra, words[words.index(name) + 1:])

    def error(self, message: str):
        missing = message.partition("the following arguments are required: ")[2].split(", ")
        positional = [m for m in missing if m and not m.startswith("-")]
        def took_it(a, o: str) -> bool:  # a word it took is no value of its (NAME=VALUE has a '='): the positional
            after = self.given[self.given.index(o) + 1:]
            taken = after[:next((i for i, w in enumerate(after) if w.startswith("-")), len(after))]
            return bool(taken) and ("=" not in taken[-1] or "=" not in str(a.metavar or ""))

        used = [o for a in self._actions if a.nargs in ("+", "*") for o in a.option_strings
                if o in self.given and took_it(a, o)]
        if positional and used:  # `evaluate --set motor_kw=90 CONFIG`: --set took CONFIG as one of its values
            message += f" ({used[0]} takes every word after it: put {positional[0].upper()} before it)"
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The ``bev-mdo`` parser. With ``argv``, only the subcommand it names gets its full parser
    (its module is imported); every other subcommand is listed by name and help. Without
    ``argv``, every module is imported and registered (the full parser, for documentation)."""
    from bev_mdo import __version__

    parser = _Parser(
        prog="bev-mdo",
        description="Distributed MDO of battery-electric-vehicle powertrains over ROS 2.",
    )
    parser.add_argument("--version", action="version", version=f"bev-mdo {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", action=_Commands)
    sub.required = True
    chosen = _chosen(argv) if argv is not None else None
    for command, (module, help_text) in SUBCOMMANDS.items():
        if command in sub.choices:
            continue  # registered with another command of its module (sweep and compare)
        if argv is None or command == chosen or module == SUBCOMMANDS.get(chosen, ("",))[0]:
            importlib.import_module(f"bev_mdo.cli.{module}").register(sub)
            if command not in sub.choices:
                raise RuntimeError(f"bev_mdo.cli.{module}.register() did not add the {command!r} subcommand")
        else:
            sub.add_parser(command, help=help_text, add_help=False)
    return parser


def main(argv: list[str] | None = None) -> int:
    process = argv is None  # the `bev-mdo` process itself (not a call from Python)
    if process:
        native_output_to_stderr()
    argv = sys.argv[1:] if argv is None else list(argv)
    dump_stacks_on_sigusr1()
    if threading.current_thread() is not threading.main_thread():
        return _main(argv)
    previous = interrupts.install()  # SIGTERM like SIGINT: unwind, close the bag, exit 143
    if process:  # the launcher watchdog's participant goes at exit: a hang there cannot eat the result
        defer_teardowns()
    try:
        status = _main(argv, process)
    finally:
        if not process:  # the process keeps its handlers to its end: after the work, a signal ends it at once
            interrupts.restore(previous)
    if process:
        if "rclpy" in sys.modules:  # the work is done: its ROS teardown may not hang the exit
            bound_exit()
        end_process(status)  # the exit handlers, then the end (no finalization with SIGINT at its default)
    return status


def _main(argv: list[str], process: bool = False) -> int:
    try:
        parser = build_parser(argv)  # imports the subcommand's module: numpy, scipy, ... (0.1-0.6 s)
        args, extra = parser.parse_known_args(argv)
        if extra:  # said by the (sub)command's parser they were given to, naming it and its --help
            parser.chosen(args, extra, argv).error(f"unrecognized arguments: {' '.join(extra)}")
    except (KeyboardInterrupt, Exception) as exc:  # a signal during the imports: its line, not a traceback
        if not isinstance(exc, KeyboardInterrupt) and interrupts.pending() is None:
            raise  # a subcommand module that fails to import raises
        status = _interrupted(exc)
    else:
        status = _run(args, process)
    if process:  # (after a failure's or a signal's line) from here on a signal ends the process at once, with a line
        interrupts.work_done(status)
    return status


def _run(args, process: bool = False) -> int:
    """The subcommand, its output flushed; its exit status (a user mistake, a signal, a failure: one line)."""
    try:
        with _notes_to_stderr(args.command):
            status = int(args.func(args) or 0)
        interrupts.check()  # a signal that code on the way swallowed (a ctypes callback, a bare except) is not lost
        sys.stdout.flush()  # a closed pipe shows here, not in the interpreter's exit
        if process:  # the output is written: from here on a signal ends the process at once, with a line (a signal
            interrupts.work_done(status)  # taken before, up to work_done's first line, is caught just below)
        return status
    except KeyboardInterrupt as exc:  # SIGINT, or Terminated (SIGTERM): what the bag holds, what was printed
        return _interrupted(exc)
    except SystemExit as exc:  # rich's Console ends a write into a closed pipe with SystemExit(1)
        if isinstance(exc.__context__, BrokenPipeError):
            return _closed_pipe()
        raise
    except Exception as exc:  # noqa: BLE001 - a user mistake, or a failure: one line
        if interrupts.pending() is not None:  # what a signal left behind (compiled code's SystemError, a cut import)
            return _interrupted(exc)
        if isinstance(exc, BrokenPipeError):
            return _closed_pipe()
        from bev_mdo.api.errors import ModelFailed

        if isinstance(exc, (ValueError, FileNotFoundError, IsADirectoryError, PermissionError)):  # a user mistake
            status, line = STARTUP_GAVE_UP_STATUS if isinstance(exc, StartupGaveUp) else 2, _named(exc, where=False)
        elif isinstance(exc, ModelFailed):  # the model gave no value where the method needs one: as a failed point
            status, line = 1, str(exc)
        else:  # the run failed (its optimiser raised)
            status, line = RUN_FAILED_STATUS, _named(exc)
        print(f"bev-mdo {args.command}: error: {line}", file=sys.stderr)
        return status


def _interrupted(exc: BaseException) -> int:
    """The end of a command a signal stopped: its lines on stderr (what the bag holds, what was printed), exit status
    130, or 143 for SIGTERM. ``exc``: the signal's exception, or whatever surfaced after the signal fired (a
    SystemError of compiled code whose callback it cut, an ImportError of a module whose initialisation it cut)."""
    if not isinstance(exc, KeyboardInterrupt):
        exc = interrupts.pending()()
    for line in interrupts.interrupted_lines(exc):
        print(line, file=sys.stderr)
    return 143 if isinstance(exc, Terminated) else 130


LONGEST_ERROR = 1000  # characters of an error line; the rest of a longer one is left out, its ends kept
RUN_FAILED_STATUS = 7  # an unexpected error stopped the command (a bag is closed with every finished iteration)


def _named(exc: BaseException, where: bool = True) -> str:
    """One line for an unexpected error: its type, the first line of its message and where it was raised;
    without ``where``, a user mistake's: the first line of its message alone (its type when it has none)."""
    msg = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    if len(msg) > LONGEST_ERROR:  # a 900,000-item list where a number goes was echoed whole: 4.5 MB on one line
        msg = f"{msg[:LONGEST_ERROR - 200]} ... ({len(msg) - LONGEST_ERROR} characters left out) ... {msg[-200:]}"
    if not where:
        return msg or type(exc).__name__
    frames = traceback.extract_tb(exc.__traceback__)
    where = f" (raised at {os.path.basename(frames[-1].filename)}:{frames[-1].lineno})" if frames else ""
    return f"{type(exc).__name__}{': ' + msg if msg else ''}{where}"


@contextlib.contextmanager
def _notes_to_stderr(command: str):
    """Notes the models raise as warnings (e.g. models.cycles.CycleNote) are printed once each as
    ``bev-mdo <command>: note: ...`` on stderr (stdout stays the command's output)."""
    from bev_mdo.models.cycles import CycleNote

    with warnings.catch_warnings():
        original, seen = warnings.showwarning, set()

        def show(message, category, filename, lineno, file=None, line=None):
            if not issubclass(category, CycleNote):
                original(message, category, filename, lineno, file, line)
            elif str(message) not in seen:  # the config is loaded more than once per command
                seen.add(str(message))
                print(f"bev-mdo {command}: note: {message}", file=sys.stderr)

        warnings.showwarning = show
        warnings.simplefilter("always", CycleNote)
        yield


def native_output_to_stderr() -> None:
    """Keep stdout for bev-mdo's own output (``--json``, tables): native libraries write to file
    descriptor 1 behind Python's back (Fast DDS logs its errors with std::cout, e.g.
    ``[RTPS_TRANSPORT_SHM Error] Failed init_port``), which corrupted ``--json`` for a pipe reader.
    File descriptor 1 is pointed at stderr; ``sys.stdout`` writes to a duplicate of the real stdout.
    Child processes inherit descriptor 1 = stderr (the launcher sends nodes' output to their logs)."""
    try:
        if sys.stdout is None or sys.stdout.fileno() != 1 or sys.stderr is None or sys.stderr.fileno() != 2:
            return
        sys.stdout.flush()
        real = os.dup(1)
        os.set_inheritable(real, False)
        os.dup2(2, 1)
    except (OSError, ValueError, AttributeError):  # no real descriptors (embedded, closed): leave as is
        return
    # line-buffered into a file or a pipe too: an optimisation's progress lines came at its end (block-buffered)
    sys.stdout = os.fdopen(real, "w", buffering=1, encoding=sys.stdout.encoding, errors=sys.stdout.errors)


def _closed_pipe() -> int:
    """The reader of stdout went away (``bev-mdo bag info BAG | head``): stop quietly, like a
    command killed by SIGPIPE (exit status 141), without a traceback at interpreter exit."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass
    return 141


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
