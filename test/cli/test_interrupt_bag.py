"""A bag is complete up to the last finished iteration, whatever stops the run: SIGINT (exit 130) and
SIGTERM (exit 143) during an in-process (differential evolution, the Chebyshev-proxy pairwise optimiser)
or ROS optimisation and during `pareto` and `sweep` leave a bag that
rosbags and mcap open without repair, with one record per finished iteration. Only SIGKILL leaves a
bag that needs `bev-mdo bag repair`, which then recovers every finished iteration.

The runs are stopped once they printed some progress (or the bag holds some fronts): conditions,
not sleeps."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from bev_mdo.testing import REPO

EXIT = {signal.SIGINT: 130, signal.SIGTERM: 143}
CONFIG = REPO / "config" / "leaf_nedc.yaml"


def _start(cwd: Path, *argv: str) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(REPO), "PYTHONUNBUFFERED": "1"}
    # SIGINT back to its default in the child: a suite started as a shell's background job inherits
    # SIGINT ignored, and Python then installs no KeyboardInterrupt handler (as for Ctrl-C on a `&` job)
    return subprocess.Popen([sys.executable, "-m", "bev_mdo", *argv], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env, cwd=cwd,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def _communicate(p: subprocess.Popen, timeout_s: float = 180) -> tuple[str, str]:
    """(stdout, stderr) of a signalled run; a run that outlives its signal is killed, not left behind.
    Read through the file objects, not with communicate(): that reads the raw pipes and drops lines
    a caller's iteration over p.stdout already buffered (and with them iterations the bag holds)."""
    err: list[str] = []
    drain = threading.Thread(target=lambda: err.append(p.stderr.read()), daemon=True)
    drain.start()
    killer = threading.Timer(timeout_s, p.kill)
    killer.start()
    try:
        out = p.stdout.read()
        drain.join()
        p.wait()
    finally:
        outlived = not killer.is_alive()
        killer.cancel()
    if outlived:
        raise subprocess.TimeoutExpired(p.args, timeout_s)
    return out, err[0]


def _stop_after_progress(p: subprocess.Popen, sig: int, lines: int) -> tuple[int, list[str], str]:
    """Send `sig` once the run printed `lines` progress lines; (exit status, every progress line, stderr)."""
    seen = []
    for line in p.stdout:
        if line.startswith("iter"):
            seen.append(line)
            if len(seen) >= lines:
                break
    assert len(seen) == lines, "the run ended before it was interrupted"
    p.send_signal(sig)
    out, err = _communicate(p)
    return p.returncode, seen + [l for l in out.splitlines() if l.startswith("iter")], err


def _complete_records(bag: Path, topic: str) -> list:
    """The messages on `topic` as rosbags reads them, after checking that mcap finds the file complete
    (summary and footer written: no repair needed) with the same count."""
    from mcap.reader import make_reader
    from rosbags.highlevel import AnyReader

    (mcap_file,) = bag.glob("*.mcap")
    with open(mcap_file, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None, "no summary: the bag was not closed"
        by_mcap = sum(1 for _, ch, _ in reader.iter_messages() if ch.topic == topic)
    with AnyReader([bag]) as reader:
        conns = [c for c in reader.connections if c.topic == topic]
        msgs = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections=conns)]
    assert len(msgs) == by_mcap
    return msgs


def _check_iterations(bag: Path, printed: list[str], err: str | None = None) -> None:
    recs = _complete_records(bag, "/bev_mdo/iteration")
    # one record per finished iteration, numbered from 1 without gaps; a record is written just
    # before its progress line is printed, so a signal between the two leaves one more record
    assert len(printed) <= len(recs) <= len(printed) + 1, (len(printed), len(recs))
    assert [int(r.sequence) for r in recs] == list(range(1, len(recs) + 1))
    assert [int(r.iteration) for r in recs] == list(range(len(recs)))
    if err is not None:  # the last line says where the bag is and what it holds
        assert err.strip().splitlines()[-1].startswith(
            f"bev-mdo: bag {bag.name}: {len(recs)} iteration records, every finished iteration"), err[-2000:]


@pytest.mark.parametrize("optimizer", ["differential_evolution", "chebyshev-pairwise"])
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_an_interrupted_in_process_optimisation_keeps_its_bag(tmp_path, sig, optimizer):
    p = _start(tmp_path, "optimize", str(CONFIG), "--transport", "inprocess", "--optimizer", optimizer, "--bag", "b")
    status, printed, err = _stop_after_progress(p, sig, 3)
    assert status == EXIT[sig], err[-2000:]
    assert "Traceback" not in err
    _check_iterations(tmp_path / "b", printed, err)


def test_a_sigkilled_in_process_bag_is_repaired_with_every_finished_iteration(tmp_path):
    from bev_mdo.bag.reader import open_bag
    from bev_mdo.cli import main

    p = _start(tmp_path, "optimize", str(CONFIG), "--transport", "inprocess", "--optimizer",
               "differential_evolution", "--bag", "b")
    status, printed, _ = _stop_after_progress(p, signal.SIGKILL, 3)
    assert status == -signal.SIGKILL
    bag = open_bag(tmp_path / "b")
    assert bag.truncated  # no summary: SIGKILL gives no chance to close
    assert main(["bag", "repair", str(tmp_path / "b")]) == 0
    _check_iterations(tmp_path / "b", printed)


def _fronts_in(bag: Path) -> int:
    from bev_mdo.bag.errors import BagError
    from bev_mdo.bag.reader import open_bag

    try:
        return open_bag(bag).message_count if bag.is_dir() and any(bag.glob("*.mcap")) else 0
    except BagError:  # the header is still being written
        return 0


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_an_interrupted_pareto_run_keeps_its_bag(tmp_path, sig):
    p = _start(tmp_path, "pareto", str(REPO / "config" / "topologies_artemis.yaml"), "--transport", "inprocess", "--generations", "100000", "--pop", "8",
               "--out", "out", "--no-plots")
    bag = tmp_path / "out" / "bag"
    while _fronts_in(bag) < 2:  # every front is flushed as it is written: wait until two are in
        assert p.poll() is None, p.communicate()[1][-2000:]
        try:
            p.wait(timeout=0.05)
        except subprocess.TimeoutExpired:
            pass
    written = _fronts_in(bag)
    p.send_signal(sig)
    _, err = _communicate(p)
    assert p.returncode == EXIT[sig], err[-2000:]
    fronts = _complete_records(bag, "/bev_mdo/pareto_front")
    assert len(fronts) >= written
    assert [int(f.generation) for f in fronts] == list(range(1, len(fronts) + 1))
    last = err.strip().splitlines()[-1]  # where the bag is and what it holds
    assert last == f"bev-mdo: bag {Path('out') / 'bag'}: {len(fronts)} Pareto fronts, one per finished generation", err[-2000:]


@pytest.mark.parametrize("optimizer", ["differential_evolution", "chebyshev-pairwise"])
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_an_interrupted_ros_optimisation_keeps_its_bag(tmp_path, sig, optimizer, ros_domain):
    p = _start(tmp_path, "optimize", str(CONFIG), "--optimizer", optimizer, "--bag", "b",
               "--domain-id", str(ros_domain))
    status, printed, err = _stop_after_progress(p, sig, 3)
    assert status == EXIT[sig], err[-2000:]
    assert "Traceback" not in err
    _check_iterations(tmp_path / "b", printed, err)
    from bev_mdo.bag.history import history
    from bev_mdo.bag.reader import open_bag

    # signed by default over ROS: the bag says so, and every record verifies with the run's key
    assert open_bag(tmp_path / "b").metadata["bev_mdo_signing"]["signed"] == "true"
    checks: dict = {}
    rows = history(tmp_path / "b", checks=checks)
    assert len(rows) >= len(printed) and checks["dropped"] == {} and checks["unverified"] == ""


def _shape_config(tmp_path: Path) -> Path:
    import yaml

    raw = yaml.safe_load(CONFIG.read_text())
    raw["disciplines"] = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed",
                          {"name": "shape", "class": "bad_disciplines:WrongShapeLater"}]
    raw["problem"]["constraints"]["shape_kw"] = {"upper": 1.0e9}
    config = tmp_path / "shape.yaml"
    config.write_text(yaml.safe_dump(raw, sort_keys=False))
    return config


def test_a_run_stopped_by_an_error_keeps_its_bag(tmp_path):
    """A discipline whose output turns the wrong shape stops the run (exit 2, one line); the bag is
    closed with the iterations finished before."""
    config = _shape_config(tmp_path)
    env = {**os.environ, "PYTHONPATH": f"{Path(__file__).resolve().parent}{os.pathsep}{REPO}"}
    p = subprocess.run([sys.executable, "-m", "bev_mdo", "optimize", str(config), "--transport", "inprocess",
                        "--optimizer", "differential_evolution", "--bag", "b"], capture_output=True, text=True,
                       env=env, cwd=tmp_path, timeout=300)
    assert p.returncode == 2 and "shape" in p.stderr.strip().splitlines()[-1], p.stderr[-2000:]
    printed = [l for l in p.stdout.splitlines() if l.startswith("iter")]
    assert printed, p.stdout[-2000:]
    _check_iterations(tmp_path / "b", printed)


def test_a_discipline_failing_over_ros_keeps_the_bag_of_every_iteration(tmp_path, ros_domain):
    """Over ROS the same discipline's node rejects the malformed answers, saying why (the discipline broke its
    contract): the run stops as in process, with the same one line and exit 2 (it was a failed point: the run
    went on and ended with a result table, exit 5), and the recorder's bag holds every iteration."""
    config = _shape_config(tmp_path)
    env = {**os.environ, "PYTHONPATH": f"{Path(__file__).resolve().parent}{os.pathsep}{REPO}"}
    p = subprocess.run([sys.executable, "-m", "bev_mdo", "optimize", str(config), "--optimizer",
                        "differential_evolution", "--bag", "b", "--domain-id", str(ros_domain)],
                       capture_output=True, text=True, env=env, cwd=tmp_path, timeout=600)
    assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr[-2000:]
    last = p.stderr.strip().splitlines()[-1]
    assert last.startswith("bev-mdo optimize: error: discipline 'shape': output 'shape_kw' has shape ("), last
    assert "discipline 'shape' failed" not in p.stderr and "│ feasible " not in p.stdout, p.stdout[-2000:]
    printed = [l for l in p.stdout.splitlines() if l.startswith("iter ")]  # not the closing "iterations N" line
    assert printed, p.stdout[-2000:]
    _check_iterations(tmp_path / "b", printed)


TRANSPORTS = ["inprocess", pytest.param("ros", marks=pytest.mark.ros)]


def _where(transport: str, request) -> list[str]:
    if transport == "inprocess":
        return ["--transport", "inprocess"]
    return ["--transport", "ros", "--domain-id", str(request.getfixturevalue("ros_domain"))]


def _fault_run(cwd: Path, point: str, *argv: str) -> subprocess.Popen:
    """`bev-mdo` stopped at a known point by fault_runs.py (paused waiting on stdin, or failing)."""
    here = Path(__file__).resolve().parent
    env = {**os.environ, "PYTHONPATH": f"{here}{os.pathsep}{REPO}", "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen([sys.executable, str(here / "fault_runs.py"), point, *argv], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=cwd,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def _signal_when_paused(p: subprocess.Popen, sig: int) -> tuple[int, str, dict[int, str]]:
    """Send `sig` once the run printed `paused`; (exit status, stderr, the run's children when it paused)."""
    from bev_mdo.testing import child_processes

    for line in p.stdout:
        if line.strip() == "paused":
            break
    else:
        _, err = _communicate(p)
        raise AssertionError(f"the run ended before it paused: {err[-2000:]}")
    children = child_processes(p.pid)
    p.send_signal(sig)
    _, err = _communicate(p)
    return p.returncode, err, children


# A signal the interpreter has taken (its C handler ran) but not yet acted on when the paused run's main thread
# is asleep in its wait: the state a SIGTERM leaves when it lands after the main thread's last look at its signals
# and before its blocking read of stdin (a loaded host preempted the run there), here made certain by sending
# the signal to another thread once the main thread sleeps in the kernel (not waiting for the GIL).
LOST_WAKEUP = """
import signal, threading
from pathlib import Path
from bev_mdo import interrupts
from bev_mdo.testing import wait_until
from fault_runs import _pause

task = Path(f"/proc/self/task/{threading.get_native_id()}")

def asleep():
    state = (task / "stat").read_text().rsplit(")", 1)[1].split()[0]
    return state == "S" and "futex" not in (task / "wchan").read_text()

def signal_another_thread():
    assert wait_until(asleep, 60)
    signal.pthread_kill(threading.get_ident(), signal.SIGTERM)

interrupts.install()
threading.Thread(target=signal_another_thread, daemon=True).start()
try:
    _pause()
except interrupts.Terminated:
    print("terminated in the pause")
"""


def test_a_paused_run_takes_a_signal_that_lands_just_before_its_wait(tmp_path):
    """The pause of fault_runs.py ends with a SIGTERM whenever it lands: its wait was a read of stdin, which a
    signal taken just before the read (or by another thread) does not interrupt, and the test sends no line; a
    sweep paused after three records outlived its SIGTERM by 180 s once, under load, in a clean-clone CI."""
    env = {**os.environ, "PYTHONPATH": f"{Path(__file__).resolve().parent}{os.pathsep}{REPO}"}
    line, send = os.pipe()  # its stdin, kept open and silent (as _fault_run's): the pause gets no line
    try:
        p = subprocess.run([sys.executable, "-c", LOST_WAKEUP], stdin=line, capture_output=True, text=True, env=env,
                           cwd=tmp_path, timeout=60)
    finally:
        os.close(line)
        os.close(send)
    assert p.stdout.splitlines() == ["paused", "terminated in the pause"], p.stderr[-2000:]


@pytest.mark.parametrize("transport", TRANSPORTS)
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_sweep_interrupted_while_it_records_keeps_a_readable_bag(tmp_path, sig, transport, request):
    """`sweep` records its batch once it is done, one record per design: stopped once three designs are in the
    bag (fault_runs.py pauses it there), it exits 130/143 with a bag that holds exactly those three, in
    order, and opens without repair."""
    p = _fault_run(tmp_path, "pause-after-3-records", "sweep", str(CONFIG), "--doe", "lhs", "--samples", "8",
                   "--no-plots", "--out", "o", *_where(transport, request))
    status, err, _ = _signal_when_paused(p, sig)
    assert status == EXIT[sig] and "Traceback" not in err, err[-2000:]
    recs = _complete_records(tmp_path / "o" / "bag", "/bev_mdo/iteration")
    assert [int(r.iteration) for r in recs] == [0, 1, 2]
    assert [int(r.sequence) for r in recs] == [1, 2, 3]


@pytest.mark.parametrize("transport", TRANSPORTS)
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_sweep_interrupted_in_its_batch_stops_its_nodes_and_leaves_no_bag(tmp_path, sig, transport, request):
    """Stopped while its batch is evaluated (over ROS: with its discipline nodes up), a sweep has finished no
    batch: it exits 130/143 without a traceback, writes no bag and leaves none of its processes behind."""
    p = _fault_run(tmp_path, "pause-in-batch", "sweep", str(CONFIG), "--doe", "lhs", "--samples", "8",
                   "--no-plots", "--out", "o", *_where(transport, request))
    status, err, children = _signal_when_paused(p, sig)
    assert status == EXIT[sig] and "Traceback" not in err, err[-2000:]
    assert not (tmp_path / "o" / "bag").exists()
    if transport == "ros":
        assert any("_node" in cmd for cmd in children.values()), children  # the nodes were up when it paused
    left = [cmd for pid, cmd in children.items() if Path(f"/proc/{pid}").exists()]
    assert not left, left


def _fault_run_to_end(cwd: Path, point: str, *argv: str) -> subprocess.CompletedProcess:
    p = _fault_run(cwd, point, *argv)
    out, err = _communicate(p, 600)
    return subprocess.CompletedProcess(p.args, p.returncode, out, err)


def _one_error_line(p: subprocess.CompletedProcess, command: str) -> None:
    """Exit status 7 and the last line of stderr names the coordinator's error, where it was raised; no traceback."""
    import re

    assert p.returncode == 7 and "Traceback" not in p.stderr, p.stderr[-2000:]
    lines = p.stderr.strip().splitlines()
    assert re.fullmatch(rf"bev-mdo {command}: error: RuntimeError: the coordinator fails on purpose "
                        r"\(raised at fault_runs\.py:\d+\)", lines[-1]), p.stderr[-2000:]
    assert [l for l in lines if "error" in l.lower()] == [lines[-1]], p.stderr[-2000:]


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_an_exception_in_the_pareto_coordinator_keeps_the_bag(tmp_path, transport, request):
    """The coordinator raises once generation 3 is done (fault_runs.py): exit status 7, one line, and a bag
    that opens without repair with the fronts of generations 1, 2 and 3 (over ROS: the recorder's bag)."""
    p = _fault_run_to_end(tmp_path, "fail-after-generation-3", "pareto", str(REPO / "config" / "topologies_artemis.yaml"),
                          "--generations", "20", "--pop", "8", "--out", "out", "--no-plots", *_where(transport, request))
    _one_error_line(p, "pareto")
    fronts = _complete_records(tmp_path / "out" / "bag", "/bev_mdo/pareto_front")
    assert [int(f.generation) for f in fronts] == [1, 2, 3]
    assert not any(f.final for f in fronts)


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_an_exception_in_the_sweep_coordinator_after_its_batch_keeps_the_bag(tmp_path, transport, request):
    """The coordinator raises once the batch is done, as it writes the CSV (fault_runs.py): exit status 7, one
    line, and a bag that opens without repair with one record per design of the finished batch."""
    p = _fault_run_to_end(tmp_path, "fail-after-batch", "sweep", str(CONFIG), "--doe", "lhs", "--samples", "8",
                          "--no-plots", "--out", "o", *_where(transport, request))
    _one_error_line(p, "sweep")
    recs = _complete_records(tmp_path / "o" / "bag", "/bev_mdo/iteration")
    assert [int(r.iteration) for r in recs] == list(range(8))


@pytest.mark.parametrize("transport", ["inprocess", pytest.param("ros", marks=pytest.mark.ros)])
def test_an_exception_in_the_coordinator_keeps_the_bag(tmp_path, transport, request):
    """The optimiser (coordinator side, not a discipline) raises after three iterations
    (fault_optimizers.py): the run ends with one line naming the error, exit status 7, and a bag that opens
    without repair with the start point and the three finished iterations; over ROS the recorder's bag."""
    import re

    where = ["--transport", "inprocess"] if transport == "inprocess" else \
        ["--domain-id", str(request.getfixturevalue("ros_domain"))]
    here = Path(__file__).resolve().parent
    env = {**os.environ, "PYTHONPATH": f"{here}{os.pathsep}{REPO}"}
    p = subprocess.run([sys.executable, str(here / "fault_optimizers.py"), "optimize", str(CONFIG), "--optimizer",
                        "failing-after-3", "--bag", "b", *where], capture_output=True, text=True, env=env,
                       cwd=tmp_path, timeout=600)
    assert p.returncode == 7 and "Traceback" not in p.stderr, p.stderr[-2000:]
    assert re.fullmatch(r"bev-mdo optimize: error: RuntimeError: the failing-after-3 optimiser fails on purpose "
                        r"\(raised at fault_optimizers\.py:\d+\)", p.stderr.strip().splitlines()[-1]), p.stderr[-2000:]
    printed = [l for l in p.stdout.splitlines() if l.startswith("iter ")]
    assert len(printed) == 4, p.stdout[-2000:]  # the start point and three iterations
    _check_iterations(tmp_path / "b", printed)
    assert len(_complete_records(tmp_path / "b", "/bev_mdo/iteration")) == len(printed)  # published before printed


def test_an_in_process_bag_on_a_full_disk_ends_nothing_but_the_bag(tmp_path):
    """In process the bag writer is the run's own recorder: when its disk fills up after three records
    (full_disk.py), the run goes on to its result, warns once naming the bag, and exits 3 (the recorder failed,
    as over ROS); the bag holds the three records, and `bev-mdo bag repair` makes it open in rosbags and mcap."""
    from bev_mdo.bag.reader import open_bag
    from bev_mdo.cli import main

    here = Path(__file__).resolve().parent
    env = {**os.environ, "PYTHONPATH": f"{here}{os.pathsep}{REPO}"}
    p = subprocess.run([sys.executable, str(here / "full_disk.py"), "3", "optimize", str(CONFIG), "--transport",
                        "inprocess", "--bag", "b"], capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300)
    assert p.returncode == 3 and "Traceback" not in p.stderr and "Exception ignored" not in p.stderr, p.stderr[-2000:]
    assert [l for l in p.stderr.splitlines() if l.startswith("warning:")] == [
        "warning: writing the bag b failed at iteration 3 (No space left on device); it holds the iterations before, "
        "and `bev-mdo bag repair b` makes it whole"]
    printed = [l for l in p.stdout.splitlines() if l.startswith("iter ")]
    assert len(printed) > 4 and "verdict: optimum" in p.stdout, p.stdout[-2000:]  # the run went on to its end
    assert open_bag(tmp_path / "b").truncated
    assert main(["bag", "repair", str(tmp_path / "b")]) == 0
    _check_iterations(tmp_path / "b", printed[:3])
    assert len(_complete_records(tmp_path / "b", "/bev_mdo/iteration")) == 3


def _on_disk(bag: Path, topic: str) -> int:
    """Messages on `topic` in the complete chunks of a bag being written (a recorder's holds other topics too)."""
    from bev_mdo.bag.errors import BagError
    from bev_mdo.bag.reader import open_bag

    try:
        return open_bag(bag).counts.get(topic, 0) if bag.is_dir() and any(bag.glob("*.mcap")) else 0
    except BagError:  # the header is still being written
        return 0


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_an_interrupted_ros_pareto_run_keeps_the_recorders_bag(tmp_path, sig, ros_domain):
    """Over ROS the fronts are the recorder's: stopped once two are on disk, the run stops its recorder, which
    closes the bag with every front it received, in order, readable without repair."""
    p = _start(tmp_path, "pareto", str(REPO / "config" / "topologies_artemis.yaml"), "--transport", "ros",
               "--domain-id", str(ros_domain), "--generations", "100000", "--pop", "8", "--out", "out", "--no-plots")
    bag = tmp_path / "out" / "bag"
    while _on_disk(bag, "/bev_mdo/pareto_front") < 2:  # the recorder flushes every second: two fronts on disk
        assert p.poll() is None, p.communicate()[1][-2000:]
        try:
            p.wait(timeout=0.05)
        except subprocess.TimeoutExpired:
            pass
    p.send_signal(sig)
    _, err = _communicate(p)
    assert p.returncode == EXIT[sig] and "Traceback" not in err, err[-2000:]
    fronts = _complete_records(bag, "/bev_mdo/pareto_front")
    assert len(fronts) >= 2
    assert [int(f.generation) for f in fronts] == list(range(1, len(fronts) + 1))


def test_a_run_stopped_before_its_recorder_started_names_no_bag(tmp_path):
    """Stopped during start-up, the run's directory holds the nodes' logs only: the note said
    "bag DIR: no iteration record", and `history DIR` then failed on the bag it named."""
    from bev_mdo.api.runbag import interrupted_note

    bag = tmp_path / "bags" / "run1"
    (bag / "logs").mkdir(parents=True)
    note = interrupted_note(bag)
    assert note.startswith("no bag was written") and str(bag / "logs") in note
    assert interrupted_note(tmp_path / "never").startswith("no bag was written")


@pytest.mark.parametrize("where, sig", [("exit handlers", signal.SIGINT), ("end of main", signal.SIGINT),
                                        ("exit handlers", signal.SIGTERM)])
def test_a_signal_after_the_result_is_one_line_and_ends_a_hung_teardown_at_once(tmp_path, where, sig):
    """A Ctrl-C in the last moments of `optimize`, after the result was printed and the bag closed, ended the
    process with exit status 130 and nothing on stderr (CPython resets SIGINT to its default before it tears
    the modules down), or with an atexit traceback. Now one line says the result was written and the bag is
    complete; the teardown left (here one that would hang for a minute, where the deferred ROS teardown runs,
    or at the end of main) is cut short at once, and the status is that of a signal (130, 143). The signal
    is sent from inside the teardown: no timing."""
    bag = tmp_path / "bag"
    hang = f"lambda *a: (os.kill(os.getpid(), {int(sig)}), time.sleep(60))"
    hook = (f"atexit.register({hang})" if where == "exit handlers"  # registered first: the last exit handler
            else f"cli.end_process = {hang}")
    code = "\n".join(["import atexit, os, sys, time", "from bev_mdo import cli", hook,
                      f"sys.argv = ['bev-mdo', 'optimize', {str(CONFIG)!r}, '--transport', 'inprocess', '--bag', "
                      f"{str(bag)!r}]", "sys.exit(cli.main())"])
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=tmp_path,
                       timeout=50, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    what = "interrupted" if sig == signal.SIGINT else "terminated (SIGTERM)"
    assert p.returncode == EXIT[sig], p.stderr
    assert p.stderr.splitlines()[-1] == (f"bev-mdo: {what} after the result was written; the bag {bag} is complete "
                                         f"(bev-mdo report {bag}; bev-mdo history {bag})")
    assert "Traceback" not in p.stderr and "run time" in p.stdout and "verdict: optimum" in p.stdout

    from bev_mdo.bag.history import history, read_answers
    from bev_mdo.bag.reader import open_bag

    written = open_bag(bag)
    assert not written.truncated and read_answers(written) is not None and history(written)


def test_a_process_that_ends_by_itself_keeps_its_status_and_output(tmp_path):
    """The bev-mdo process ends itself after its exit handlers (stacks.end_process): its status, stdout and
    the exit handlers' output are all there."""
    code = "\n".join(["import atexit, sys", "from bev_mdo import cli",
                      "atexit.register(lambda: print('exit handler ran', flush=True))",
                      f"sys.argv = ['bev-mdo', 'evaluate', {str(CONFIG)!r}, '--set', 'motor_kw=80', '--transport', "
                      "'inprocess']", "sys.exit(cli.main())"])
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, timeout=50,
                       env={**os.environ, "PYTHONPATH": str(REPO)})
    assert p.returncode == 0 and p.stderr == "" and p.stdout.rstrip().endswith("exit handler ran")
    assert "energy_wh_per_km" in p.stdout


def test_the_report_of_an_interrupted_run_says_it_did_not_finish(tmp_path):
    """`bev-mdo report` of a run stopped by SIGINT read like a finished run ("Final iterate", "What holds the
    design"): its first line now says that the bag holds no end-of-run record, and the iterate is the last recorded."""
    from bev_mdo.bag.report import report

    p = _start(tmp_path, "optimize", str(CONFIG), "--transport", "inprocess", "--optimizer", "differential_evolution",
               "--bag", "b")
    status, _, err = _stop_after_progress(p, signal.SIGINT, 3)
    assert status == 130, err[-2000:]
    report(tmp_path / "b", tmp_path)
    md = (tmp_path / "report.md").read_text()
    assert md.splitlines()[2].startswith("- **the run did not finish**: the bag holds no end-of-run record"), md[:600]
    assert "## Last recorded iterate (the run did not finish)" in md and "## Final iterate" not in md
    history = subprocess.run([sys.executable, "-m", "bev_mdo", "history", "b", "--csv", "-"], capture_output=True,
                             text=True, cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(REPO)}, timeout=120)
    last = history.stdout.strip().splitlines()[-1].split(",")[1]  # its last record's iteration
    assert history.returncode == 0 and "b: the run did not finish: the bag holds no end-of-run record" in history.stderr
    assert f"iteration {last} is its last recorded iterate, not a result" in history.stderr, history.stderr
