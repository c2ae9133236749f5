"""`kill -USR1 <pid>` prints where a bev_mdo process waits (bev_mdo/stacks.py), and it goes on."""
import signal
import subprocess
import sys
import types

from bev_mdo.testing import REPO


def test_sigusr1_prints_every_threads_stack_and_the_process_goes_on():
    code = "\n".join([
        "import sys, threading",
        "from bev_mdo.stacks import dump_stacks_on_sigusr1",
        "dump_stacks_on_sigusr1()",
        "ev = threading.Event()",
        "def waiting_here():",
        "    ev.wait(30)",
        "threading.Thread(target=waiting_here).start()",
        "print('ready', flush=True)",
        "sys.stdin.readline()",
        "ev.set()",
        "print('done')"])
    p = subprocess.Popen([sys.executable, "-c", code], cwd=REPO, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    assert p.stdout.readline().strip() == "ready"
    p.send_signal(signal.SIGUSR1)
    # the dump is written synchronously by the signal handler; then the process is told to finish
    out, err = p.communicate("go\n", timeout=30)
    assert p.returncode == 0 and out.strip() == "done"
    assert "waiting_here" in err and "Thread" in err


def test_a_node_stuck_past_sigint_gets_its_stacks_dumped_before_sigterm():
    """The launcher's stop: a process that ignores SIGINT is stuck; its stack lands in its log (stderr)
    before SIGTERM ends it, so a hung node can be diagnosed after the run."""
    from bev_mdo.launcher import _stop_procs

    code = "\n".join([
        "import signal, time",
        "from bev_mdo.stacks import dump_stacks_on_sigusr1",
        "dump_stacks_on_sigusr1()",
        "signal.signal(signal.SIGINT, signal.SIG_IGN)",
        "print('ready', flush=True)",
        "def stuck_here():",
        "    time.sleep(60)",
        "stuck_here()"])
    p = subprocess.Popen([sys.executable, "-c", code], cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True)
    assert p.stdout.readline().strip() == "ready"
    _stop_procs([p], 0.5)
    _, err = p.communicate(timeout=30)
    assert p.returncode == -signal.SIGTERM
    assert "stuck_here" in err


def _deadline_run(body: str, seconds: float) -> subprocess.CompletedProcess:
    code = "\n".join(["import ctypes, time", "from bev_mdo.stacks import deadline",
                      f"with deadline({seconds}):", f"    {body}", "time.sleep(1.5)", "print('after')"])
    return subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=60)


def test_a_teardown_stuck_in_c_holding_the_gil_ends_the_process_with_its_stacks():
    """A call blocked in C that holds Python's lock (ctypes.PyDLL keeps it: like a DDS destroy that never
    returns) cannot be interrupted from Python; the deadline's timer thread still ends the process."""
    p = _deadline_run("ctypes.PyDLL(None).sleep(30)", 0.5)
    assert p.returncode == -signal.SIGALRM and "after" not in p.stdout  # exit status 142 in a shell
    assert "Timeout" in p.stderr and "File" in p.stderr


def test_ctrl_c_during_the_deferred_teardown_exits_130_without_a_traceback():
    """SIGINT while the watchdog's participant is destroyed at exit (after the result) once printed an
    atexit traceback and kept exit status 0. It ends the process at once (not after the 5 s the teardown
    would take), with one line."""
    # the teardown would take 5 s, in short sleeps: a signal the kernel hands to another thread (numpy's
    # OpenBLAS workers block none) does not cut a sleep short, and Python runs its handler in the main
    # thread when that wakes; one 5 s sleep let the 2 s deadline's SIGALRM end it first (one CI run in many)
    p = _deferred_run("(os.kill(os.getpid(), signal.SIGINT), [time.sleep(0.01) for _ in range(500)])")
    assert p.returncode == 130 and p.stdout.strip() == "result"
    assert p.stderr == "bev-mdo: interrupted after the result was written\n"


def test_an_exit_that_hangs_after_the_work_is_done_is_ended_by_the_kernel():
    """bound_exit: the end of a bev-mdo process that ran ROS is bounded even where no Python timer runs
    (a C++ destructor of the middleware blocking the interpreter's exit, here an atexit handler blocked
    in C holding Python's lock): SIGALRM ends it, exit status 142."""
    code = "\n".join(["import atexit, ctypes", "from bev_mdo.stacks import bound_exit",
                      "atexit.register(lambda: ctypes.PyDLL(None).sleep(30))", "print('result', flush=True)",
                      "bound_exit(1)"])
    p = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=60)
    assert p.returncode == -signal.SIGALRM and p.stdout.strip() == "result"


def test_a_process_that_exits_in_time_keeps_its_status():
    code = "\n".join(["import sys", "from bev_mdo.stacks import bound_exit", "bound_exit(30)", "sys.exit(5)"])
    p = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=60)
    assert p.returncode == 5


def test_a_start_up_that_gives_up_is_its_own_exit_status(monkeypatch, capsys):
    """A ROS start-up wait that gives up (a discipline or the run's recorder missing while nothing changed
    on the graph) is not a user mistake (2): one line and exit status 6."""
    from bev_mdo import cli
    from bev_mdo.stacks import StartupGaveUp

    def gave_up(args):
        raise StartupGaveUp("discipline(s) ['energy'] not found on ROS domain: discovery made no progress for 20 s")

    parser = cli.build_parser(["graph", "x.yaml"])
    monkeypatch.setattr(cli, "build_parser", lambda argv: parser)
    monkeypatch.setattr(parser, "parse_known_args",
                        lambda argv: (types.SimpleNamespace(command="graph", func=gave_up), []))
    assert cli.main(["graph", "x.yaml"]) == 6
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["bev-mdo graph: error: discipline(s) ['energy'] not found on ROS domain: discovery made no "
                   "progress for 20 s"]


def test_a_teardown_that_ends_in_time_cancels_the_deadline():
    p = _deadline_run("time.sleep(0.1)", 0.5)
    assert p.returncode == 0 and p.stdout.strip() == "after" and "Timeout" not in p.stderr


def _deferred_run(*closes: str) -> subprocess.CompletedProcess:
    """A `bev-mdo`-like process: its signal handlers, teardowns deferred, each handed over, the result printed,
    the work done (interrupts.work_done, as the CLI's main says it), exit status 5."""
    code = "\n".join(["import ctypes, os, signal, sys, time", "from bev_mdo import interrupts, stacks",
                      "stacks.TEARDOWN_S = 1.0", "interrupts.install()",
                      "stacks.defer_teardowns()", *(f"stacks.teardown(lambda: {c})" for c in closes),
                      "print('result', flush=True)", "interrupts.work_done(5)", "sys.exit(5)"])
    # SIGINT back to its default in the child: a suite started as a background job inherits SIGINT ignored,
    # and Python then installs no KeyboardInterrupt handler (as for Ctrl-C on a `&` job)
    return subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=60,
                          preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def test_a_deferred_teardown_runs_at_exit_after_the_result_and_keeps_the_status():
    p = _deferred_run("print('closed', flush=True)")
    assert p.returncode == 5 and p.stdout.split() == ["result", "closed"]


def test_deferred_teardowns_run_in_the_order_they_were_left():
    """A coordinator's node is left before the context it lives in is shut down: at the exit they go in
    that order, as they would have gone at once."""
    p = _deferred_run("print('node', flush=True)", "print('context', flush=True)")
    assert p.returncode == 5 and p.stdout.split() == ["result", "node", "context"]


def test_a_deferred_teardown_that_hangs_costs_the_exit_status_not_the_result():
    """The launcher watchdog's participant hung in its destroy (seen with eight runs on one domain) once
    took the printed result with it; deferred to the exit, the result is out first and the hang is
    bounded as before: its stacks, then SIGALRM (142)."""
    p = _deferred_run("ctypes.PyDLL(None).sleep(30)")
    assert p.returncode == -signal.SIGALRM and p.stdout.strip() == "result"
    assert "Timeout" in p.stderr and "File" in p.stderr
