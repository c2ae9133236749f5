"""The hang watchdog (bev_mdo/ros/watchdog.py) on a made-up graph: a launched process that left
the ROS graph, or never reached it, is killed while it runs and restarted by the supervisor; a
node on the graph is never touched, however long; nothing is done once the launcher stops."""
from __future__ import annotations

import signal

import pytest

from bev_mdo.launcher import Launcher, NodeProcess, cpu_ticks
from bev_mdo.processes import composed_argv, discipline_argv, node_names_of
from bev_mdo.ros.watchdog import HangWatchdog
from bev_mdo.testing import PYTHON, wait_until

SLEEPER = [PYTHON, "-c", "import time; time.sleep(120)"]


def test_node_names_are_read_from_the_command_line():
    assert node_names_of(discipline_argv("energy", "c.yaml", instance="ab12")) == ["energy_node_ab12"]
    assert node_names_of(composed_argv(["vehicle_mass", "range"], "c.yaml", instance="ab12")) == [
        "vehicle_mass_node_ab12", "range_node_ab12"]
    assert node_names_of(composed_argv(["energy"], "c.yaml")) == ["energy_node"]
    assert node_names_of(SLEEPER) == []  # a process without a node name (the recorder) is not watched


@pytest.fixture
def launcher(tmp_path):
    la = Launcher({"ROS_DOMAIN_ID": "0"}, log_dir=tmp_path)
    yield la
    la.stop(timeout_s=1.0)


def test_a_node_that_leaves_the_graph_is_killed_and_restarted(launcher):
    node = launcher.add("energy", SLEEPER + ["-r", "__node:=energy_node_x"])
    launcher.supervise()
    dog = HangWatchdog(launcher, 0, silent_s=7.0, start_s=45.0)
    t0 = node.spawned_at
    first = node.proc.pid
    assert dog.check({"energy_node_x", "other"}, t0 + 1) == []
    assert node.seen
    assert dog.check({"energy_node_x"}, t0 + 1000) == []  # on the graph: never touched, however long
    assert dog.check({"other"}, t0 + 1001) == []          # gone for less than silent_s: wait
    assert dog.check({"other"}, t0 + 1007.9) == []
    assert dog.check({"other"}, t0 + 1008.1) == ["energy"]
    assert node.hangs == 1
    assert wait_until(lambda: node.restarts == 1 and node.proc.pid != first)  # the supervisor restarted it
    assert not node.seen and node.missing_since is None  # watched afresh from its restart


class Dying:
    """A process SIGKILLed that the kernel has not yet ended (poll() None): on a loaded host, the
    moment after the watchdog's kill, which a look by the coordinator blocked on the launcher's lock
    (during the watchdog's 0.3 s wait for the stack dump) meets."""

    pid, returncode = 2**22 + 1, None  # no such process: no CPU time

    def __init__(self):
        self.signals = []

    def poll(self):
        return self.returncode

    def send_signal(self, sig):
        self.signals.append(sig)

    def kill(self):
        self.signals.append(signal.SIGKILL)

    def wait(self, timeout=None):
        self.returncode = -9
        return self.returncode


def test_a_node_killed_as_hung_is_recovering_before_the_kernel_ended_it_and_is_killed_once(launcher):
    node = NodeProcess("vehicle_mass", [], proc=Dying(), ros_names=("vehicle_mass_node_x",), seen=True)
    launcher.nodes.append(node)
    dog = HangWatchdog(launcher, 0, silent_s=7.0, start_s=45.0)
    assert dog.check(set(), 100.0) == [] and launcher.recovering("vehicle_mass")  # gone from the graph
    assert dog.check(set(), 107.5) == ["vehicle_mass"] and node.proc.poll() is None
    assert launcher.recovering("vehicle_mass")  # killed, still ending: a coordinator's look must see the restart
    assert dog.check(set(), 1000.0) == [] and node.hangs == 1  # not killed (nor counted) twice
    assert node.proc.signals.count(signal.SIGKILL) == 1
    node.proc.wait()
    assert launcher.recovering("vehicle_mass")  # dead, not yet restarted


def test_a_node_that_never_appears_is_killed_after_start_s_once_it_uses_no_cpu(launcher, tmp_path):
    asleep = tmp_path / "asleep"
    # it says when its interpreter's start-up (which uses CPU) is over: the looks below are close in real
    # time, and a process still importing between them is rightly "busy" (a clean-clone CI run saw that)
    node = launcher.add("energy", [PYTHON, "-c", f"import pathlib, time; pathlib.Path({str(asleep)!r}).touch(); "
                                   "time.sleep(120)", "-r", "__node:=energy_node_x"])
    assert wait_until(asleep.exists)
    dog = HangWatchdog(launcher, 0, silent_s=7.0, start_s=45.0)
    assert dog.check(set(), node.spawned_at + 44) == []
    assert dog.check(set(), node.spawned_at + 45) == []  # its CPU time is read for the first time
    assert dog.check(set(), node.spawned_at + 52.5) == ["energy"]  # a sleeper: no CPU for 7 s
    assert wait_until(lambda: node.proc.poll() is not None)  # killed (no supervisor here: not restarted)


def test_a_node_still_starting_on_a_loaded_host_is_not_killed(launcher):
    node = launcher.add("energy", [PYTHON, "-c", "while True: pass", "-r", "__node:=energy_node_x"])
    dog = HangWatchdog(launcher, 0, silent_s=7.0, start_s=45.0)
    t = node.spawned_at + 45
    for _ in range(5):
        assert dog.check(set(), t) == []
        seen = node.cpu_ticks
        assert wait_until(lambda: cpu_ticks(node.proc.pid) > seen)  # it computes between looks, as a node importing does
        t += 8.0  # each look more than silent_s after the one before
    assert node.proc.poll() is None and node.hangs == 0


def test_nothing_is_killed_once_the_launcher_stops_or_for_unwatched_nodes(launcher):
    watched = launcher.add("energy", SLEEPER + ["-r", "__node:=energy_node_x"])
    plain = launcher.add("recorder", SLEEPER, restart=False)
    dog = HangWatchdog(launcher, 0, silent_s=7.0, start_s=45.0)
    assert dog.check({"energy_node_x"}, watched.spawned_at + 1) == []
    assert dog.check(set(), watched.spawned_at + 100) == []
    assert dog.check(set(), watched.spawned_at + 107) == ["energy"]
    assert plain.proc.poll() is None and plain.hangs == 0
    launcher._stopping.set()
    w2 = launcher.add("mass", SLEEPER + ["-r", "__node:=vehicle_mass_node_x"])
    assert dog.check(set(), w2.spawned_at + 1000) == []
    assert w2.proc.poll() is None


def test_kill_reaches_a_live_process_or_says_there_is_none(launcher):
    """Launcher.kill (fault injection) on a process that already exited and is not yet restarted
    raises instead of counting a kill that reached nothing (test_faults' kills raced the restart)."""
    node = launcher.add("energy", SLEEPER)  # not supervised: nothing restarts it
    first = launcher.kill("energy")
    assert first == node.proc.pid and node.proc.returncode is not None
    with pytest.raises(ProcessLookupError, match="energy is not running"):
        launcher.kill("energy")
    launcher.supervise()
    assert wait_until(lambda: node.restarts == 1 and node.proc.pid != first)
    assert launcher.kill("energy") == node.proc.pid


def test_stop_destroys_the_watchdogs_participant_in_the_callers_thread(launcher, ros_domain):
    """Not left to the watching (daemon) thread: a participant still being deleted there when the process
    exits meets Fast DDS's destructors (the factory's waits on it), and a finished run never ended."""
    dog = HangWatchdog(launcher, ros_domain, period_s=0.05).start()
    assert wait_until(lambda: dog._node is not None)
    ctx = dog._ctx
    dog.stop()
    assert not dog._thread.is_alive() and not ctx.ok() and dog._ctx is None
