"""Start, supervise and stop the node processes (what `ros2 launch` would do).

Each discipline runs in its own process (`python -m bev_mdo.ros.run <exe>`, the same
entry point `ros2 run bev_mdo <exe>` reaches). A supervisor thread restarts a node
that dies while the run is on. `stop()` sends SIGINT, then SIGTERM, then SIGKILL.
"""
from __future__ import annotations

import contextlib
import os
import re
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Sequence

from bev_mdo.processes import node_names_of, plan_processes
from bev_mdo.ros.watchdog import HangWatchdog

FIRST_STOP_S = 30.0  # how long Launcher.stop gives the nodes stopped first (the recorder) after SIGINT


def _die_with_parent() -> None:
    """In the child: SIGINT and SIGTERM at their defaults (a job a shell started with ``&`` inherits SIGINT ignored, so
    Launcher.stop's SIGINT reached no node: 30 s later SIGUSR1, a stack dump in its log, and SIGTERM), and SIGTERM
    if the launcher dies (even by SIGKILL), so no node is orphaned (Linux)."""
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, signal.SIG_DFL)
    try:
        import ctypes

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except OSError:
        pass


@dataclass
class NodeProcess:
    """One supervised node process."""

    label: str
    argv: list[str]
    log_path: Path | None = None
    proc: subprocess.Popen | None = None
    restarts: int = 0
    restart_times: list[float] = field(default_factory=list)
    restart: bool = True            # False: a death is reported (``died``), never restarted
    died: int | None = None         # exit status of a node that died and was not restarted
    died_at: float | None = None    # when the supervisor saw it die (time.monotonic())
    ros_names: tuple[str, ...] = ()  # the ROS node names it serves (node_names_of; watched by watchdog.py)
    spawned_at: float = 0.0         # time.monotonic() of its (re)start
    seen: bool = False              # on the ROS graph since its (re)start
    missing_since: float | None = None
    hangs: int = 0                  # times the watchdog killed it as hung (each also counts as a restart)
    cpu_ticks: int = -1             # its CPU time when last read (clock ticks; cpu_ticks())
    cpu_changed_at: float = 0.0     # when that last changed (time.monotonic())
    frozen: bool = False            # found stopped (SIGSTOP, state T) when the launcher stopped it: killed at once
    killed: bool = False            # SIGKILLed by the watchdog, its successor not yet spawned (Launcher.recovering)

    def busy(self, now: float, within_s: float) -> bool:
        """Whether its process used CPU in the last `within_s` seconds (a node still importing and
        starting on a loaded host does; one hung in the middleware does not)."""
        ticks = cpu_ticks(self.proc.pid) if self.proc is not None else -1
        if ticks != self.cpu_ticks:
            self.cpu_ticks, self.cpu_changed_at = ticks, now
        return ticks >= 0 and now - self.cpu_changed_at < within_s


def process_state(pid: int) -> str:
    """The state letter of process `pid` (Linux /proc: R, S, D, T stopped, Z, ...; '' if it is gone)."""
    try:
        return Path(f"/proc/{pid}/stat").read_bytes().rsplit(b")", 1)[1].split()[0].decode()
    except (OSError, IndexError):
        return ""


def cpu_ticks(pid: int) -> int:
    """User + system CPU time of process `pid` in clock ticks (Linux /proc; -1 if it is gone)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_bytes().rsplit(b")", 1)[1].split()
        return int(fields[11]) + int(fields[12])
    except (OSError, IndexError, ValueError):
        return -1


def _stop_procs(procs, timeout_s: float) -> None:
    """SIGINT, then SIGTERM, then SIGKILL, waiting for each step. A process still alive after SIGINT is
    stuck: it first gets SIGUSR1, so every thread's stack lands in its log (bev_mdo/stacks.py)."""
    for sig, wait in ((signal.SIGINT, timeout_s), (signal.SIGTERM, 2.0), (signal.SIGKILL, 2.0)):
        alive = [p for p in procs if p is not None and p.poll() is None]
        if not alive:
            break
        if sig == signal.SIGTERM:
            for p in alive:
                with contextlib.suppress(ProcessLookupError):
                    p.send_signal(signal.SIGUSR1)
            time.sleep(0.2)
        for p in alive:
            try:
                p.send_signal(sig)
            except ProcessLookupError:
                pass
        deadline = time.monotonic() + wait
        for p in alive:
            try:
                p.wait(timeout=max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                pass


class Launcher:
    """Runs node processes with a given environment and keeps them alive."""

    def __init__(self, env: Mapping[str, str], log_dir: str | Path | None = None, max_restarts: int = 20):
        from bev_mdo.shm import remove_orphans

        remove_orphans()  # Fast DDS files of killed processes (ours, earlier): nobody else removes them
        self.env = dict(env)
        repo = str(Path(__file__).resolve().parents[1])
        self.env["PYTHONPATH"] = repo + os.pathsep + self.env.get("PYTHONPATH", "")
        self.env["PYTHONUNBUFFERED"] = "1"
        self.log_dir = Path(log_dir) if log_dir else None
        self._set_log_dir = False
        if self.log_dir is not None:
            # The nodes' ROS logs go with theirs, in the run's folder, not to ~/.ros/log; so does this
            # process's (its coordinator, the watchdog) unless ROS_LOG_DIR says otherwise: rcl reads it
            # once, at the process's first rclpy.init, which comes after this.
            self.env["ROS_LOG_DIR"] = str(self.log_dir.resolve() / "ros")
            self._set_log_dir = "ROS_LOG_DIR" not in os.environ  # (stop: taken back, as a library run should)
            os.environ.setdefault("ROS_LOG_DIR", self.env["ROS_LOG_DIR"])
        self.max_restarts = max_restarts
        self.nodes: list[NodeProcess] = []
        self._lock = threading.Lock()
        self._stopping = threading.Event()
        self._thread: threading.Thread | None = None
        self._watchdog = None

    def add(self, label: str, argv: Sequence[str], restart: bool = True) -> NodeProcess:
        """Register and start one node process (`restart`: whether the supervisor restarts it)."""
        log = (self.log_dir / f"{label}.log") if self.log_dir else None
        node = NodeProcess(label, list(argv), log, restart=restart, ros_names=tuple(node_names_of(argv)))
        self._spawn(node)
        with self._lock:
            self.nodes.append(node)
        return node

    def _spawn(self, node: NodeProcess) -> None:
        if node.log_path:
            node.log_path.parent.mkdir(parents=True, exist_ok=True)
            out = open(node.log_path, "ab")
        else:
            out = subprocess.DEVNULL
        node.spawned_at, node.seen, node.missing_since, node.killed = time.monotonic(), False, None, False
        # Own process group, so a Ctrl-C in the terminal reaches only us and we stop the children in
        # order; but our session, so the kernel's CPU scheduler (autogroups, one per session) weighs a
        # run's nodes with its command: a session per node gave each node the share of a whole run, and
        # eight commands started from one session starved against their 64 nodes (docs/scaling.md).
        node.proc = subprocess.Popen(node.argv, env=self.env, stdout=out, stderr=subprocess.STDOUT,
                                     stdin=subprocess.DEVNULL, process_group=0,
                                     preexec_fn=_die_with_parent)
        if out is not subprocess.DEVNULL:
            out.close()

    def supervise(self, interval_s: float = 0.1, watch_hangs: bool = False) -> None:
        """Start the background thread that restarts nodes that die; with `watch_hangs`, also the
        watchdog that kills (for a restart) a node whose process lives but whose participant went
        silent on the ROS graph (watchdog.py)."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._watch, args=(interval_s,), daemon=True)
            self._thread.start()
        if watch_hangs and self._watchdog is None:
            self._watchdog = HangWatchdog(self, int(self.env.get("ROS_DOMAIN_ID", "0"))).start()

    def _watch(self, interval_s: float) -> None:
        while not self._stopping.wait(interval_s):
            with self._lock:
                for node in self.nodes:
                    if node.proc is not None and node.proc.poll() is not None and not self._stopping.is_set():
                        if not node.restart:
                            if node.died is None:
                                node.died = node.proc.returncode
                                node.died_at = time.monotonic()
                                print(f"[launcher] {node.label} exited with {node.died}; not restarted",
                                      file=sys.stderr)
                            continue
                        if node.restarts >= self.max_restarts:
                            continue
                        node.restarts += 1
                        node.restart_times.append(time.monotonic())
                        print(f"[launcher] {node.label} exited with {node.proc.returncode}; restarting "
                              f"({node.restarts}/{self.max_restarts})", file=sys.stderr)
                        self._spawn(node)

    def progress(self) -> tuple:
        """Start-up progress of the processes not yet on the ROS graph (``seen``, kept by the hang
        watchdog): their restarts and CPU time. A node process still importing on a loaded host
        is progress even before discovery shows it (fastwait.until)."""
        with self._lock:
            return tuple((n.label, n.restarts, cpu_ticks(n.proc.pid) if n.proc is not None else -1)
                         for n in self.nodes if not n.seen)

    def died_within(self, window_s: float) -> bool:
        """Whether a supervised node died (and was restarted, or not) in the last `window_s` seconds."""
        since = time.monotonic() - window_s
        with self._lock:
            return any(t >= since for n in self.nodes for t in n.restart_times) or any(
                n.died_at is not None and n.died_at >= since for n in self.nodes)

    def recovering(self, discipline: str) -> bool:
        """Whether a supervised process serving `discipline` is being restarted: gone from the ROS graph while
        it runs (the watchdog kills it SILENT_S later), killed by the watchdog (even before the kernel has
        ended it: poll() still None), dead and not yet restarted, or restarted and not yet back on the graph
        (the coordinator's retries wait for it: Orchestrator.recovering)."""
        with self._lock:
            return any(n.restart and n.proc is not None
                       and discipline in n.label.rsplit("/", 1)[-1].split("#")[0].split("+")  # topology/a+b#k
                       and (n.missing_since is not None or (n.restarts and not n.seen)
                            or ((n.killed or n.proc.poll() is not None) and n.restarts < self.max_restarts))
                       for n in self.nodes)

    def kill(self, label: str, sig: int = signal.SIGKILL, wait: bool = True) -> int:
        """Send a signal to a node process (for fault-injection tests); returns its pid.

        With `wait`, return only once that process has exited (the supervisor, which
        needs the same lock, cannot restart it before). ProcessLookupError if the node's process
        has already exited and not yet been restarted: a signal to it would reach nothing.
        """
        with self._lock:
            node = self.node(label)
            if node.proc.poll() is not None:
                raise ProcessLookupError(f"{label} is not running (exited with {node.proc.returncode})")
            pid = node.proc.pid
            node.proc.send_signal(sig)
            if wait:
                node.proc.wait()
        return pid

    def node(self, label: str) -> NodeProcess:
        """The supervised node process with this label (KeyError if none)."""
        for n in self.nodes:
            if n.label == label:
                return n
        raise KeyError(f"no node labelled {label!r}; have {[n.label for n in self.nodes]}")

    def remove(self, label: str, timeout_s: float = 5.0) -> None:
        """Stop one node for good (it is not restarted) and forget it."""
        with self._lock:
            node = self.node(label)
            self.nodes.remove(node)
        _stop_procs([node.proc], timeout_s)

    def stop(self, timeout_s: float = 5.0, first: tuple[str, ...] = ()) -> None:
        """Stop every node: SIGINT, then SIGTERM, then SIGKILL. Idempotent.

        Nodes labelled in `first` are stopped (and waited for) before the others: a
        recorder drains its queue while the publishers are still alive to deliver it.
        A second Ctrl-C or SIGTERM meanwhile is taken once every node is stopped (interrupts.held): it
        cut this short, and a node busy in one long numpy/numba call, deaf to SIGINT and SIGTERM, was left
        running before its SIGKILL.
        """
        from bev_mdo import interrupts

        with interrupts.held():
            self._stop(timeout_s, first)

    def _stop(self, timeout_s: float, first: tuple[str, ...]) -> None:
        self._stopping.set()
        if self._watchdog is not None:
            self._watchdog.stop()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        with self._lock:
            for n in self.nodes:  # a frozen process cannot take SIGINT or SIGTERM: killed now, not waited for
                if n.proc is not None and n.proc.poll() is None and process_state(n.proc.pid) == "T":
                    n.frozen = True
                    with contextlib.suppress(ProcessLookupError):
                        n.proc.kill()
            early = [n.proc for n in self.nodes if n.proc is not None and n.label in first]
            procs = [n.proc for n in self.nodes if n.proc is not None and n.label not in first]
        if early:  # a recorder drains its queue (up to 10 s) and closes the bag: slow on a crowded host
            _stop_procs(early, max(timeout_s, FIRST_STOP_S))
        _stop_procs(procs, timeout_s)
        from bev_mdo.shm import remove_orphans

        # a node SIGTERMed or SIGKILLed above (a recorder still in its ROS teardown 30 s after SIGINT, seen
        # stuck destroying a publisher on a crowded host) leaves its Fast DDS files: removed now, not at the next start
        remove_orphans()
        if self._set_log_dir and os.environ.get("ROS_LOG_DIR") == self.env["ROS_LOG_DIR"]:
            del os.environ["ROS_LOG_DIR"]  # the next run of a Python caller logs into its own folder, not this one

    def __enter__(self) -> "Launcher":
        return self

    def __exit__(self, *exc) -> None:
        self.stop()


def prepare_run_dir(config, logs: Path, key_dir: Path) -> tuple:
    """(config with its ros section signed by a per-run key unless it names its own key or signing is
    off, the resolved config written to ``logs/config.yaml``): what nodes and recorder read."""
    import yaml

    from bev_mdo.config import RunConfig, plain
    from bev_mdo.protocol.signing import with_run_key

    logs.mkdir(parents=True, exist_ok=True)
    config = config.with_run_key(key_dir) if isinstance(config, RunConfig) else with_run_key(config, key_dir)
    resolved = logs / "config.yaml"
    resolved.write_text(yaml.safe_dump(plain(config), sort_keys=False))
    return config, resolved


class OwnSuite:
    """The config's discipline nodes started for one command (``evaluate``, ``sweep``,
    ``sensitivity``, ``check-totals`` over ROS without ``--attach``), as ``optimize`` starts them: bound to a fresh run id and, unless
    ``ros.signing: false`` or a ``ros.sign_key_file`` is configured, signing with a fresh per-run
    key (mode 0600) in ``work_dir/.keys`` — a path in the resolved config the nodes read, never
    on a command line, in the environment or in a log. ``config`` (after ``start``) is the
    resolved config the command's own evaluator must use (its key and run id included).
    ``stop()`` stops the nodes and deletes ``work_dir`` when this object created it."""

    def __init__(self, config: Mapping, ros: Mapping, work_dir: str | Path | None = None):
        import tempfile
        import uuid

        self._own_dir = work_dir is None
        self.work_dir = Path(work_dir or tempfile.mkdtemp(prefix="bev_mdo_suite_"))  # mkdtemp: mode 0700
        self.run_id = uuid.uuid4().hex[:16]
        from bev_mdo.config import RunConfig

        self.config = RunConfig.of(config).with_ros(ros)
        self.ros = dict(ros)
        self.launcher: Launcher | None = None

    def start(self) -> "OwnSuite":
        from bev_mdo.ros_settings import ros_environment

        logs = self.work_dir / "logs"
        self.config, resolved = prepare_run_dir(self.config, logs, self.work_dir / ".keys")
        self.launcher = Launcher(ros_environment(self.ros), log_dir=logs)
        try:
            for label, argv in plan_processes(list(self.config.names), str(resolved.resolve()),
                                              run_id=self.run_id, instance=self.run_id[:8]):
                self.launcher.add(label, argv)
            self.launcher.supervise(watch_hangs=True)
        except BaseException:
            self.stop()
            raise
        return self

    def stop(self) -> None:
        import shutil

        try:
            if self.launcher is not None:
                self.launcher.stop()
                self.launcher = None
        finally:
            if self._own_dir:
                shutil.rmtree(self.work_dir, ignore_errors=True)

    def __enter__(self) -> "OwnSuite":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()


def start_recorder(launcher: Launcher, bag: Path, resolved: Path, run_id: str) -> int:
    """Start the recorder node of a run writing `bag`; returns how many extra subscribers it adds per topic."""
    # Not restarted: a second recorder cannot reopen the bag the first one was writing (the run ends
    # with a warning and status 3 instead, the bag repaired up to the recorder's death).
    # a node name of its own: the coordinator knows the run's recorder by its declaration, which names it
    launcher.add("recorder", [sys.executable, "-m", "bev_mdo.ros.run", "recorder_node", "--output", str(bag),
                              "--config", str(resolved.resolve()), "--run-id", run_id,
                              "--ros-args", "-r", f"__node:=recorder_{re.sub(r'[^A-Za-z0-9_]', '_', run_id)[:24]}"],
                 restart=False)
    return 1
