"""No stall on a dead reader or writer; a dead recorder is reported, never crash-looped.

`bev-mdo optimize` records the Leaf problem; once the first iteration is printed, vehicle_mass
(a reader of the coordinator's request topics) and the recorder are SIGKILLed. The run still
finishes with the in-process optimum; vehicle_mass is restarted; the recorder is not (its bag
cannot be reopened by a second one): the run ends with a one-line warning and status 3 and the
bag, repaired on the spot, opens in rosbags and in mcap as it is. The same with both killed once
the LAST iteration is printed (the kill lands in the run's tail: nothing after the optimiser may
wait for the dead node). The time after the optimisation (acknowledgements, shutdown) is printed
beside an undisturbed run's; the figure goes to bench (no timing assertion here).
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import threading
import time
from pathlib import Path

import pytest


from bev_mdo.config import load_config, resolve_disciplines  # noqa: E402
from bev_mdo.launcher import process_state  # noqa: E402
from bev_mdo.mdo.driver import run_optimization  # noqa: E402
from bev_mdo.mdo.evaluator import InProcessEvaluator  # noqa: E402
from bev_mdo.testing import PYTHON, child_processes, leaf_config_file, ros_env, wait_until  # noqa: E402


@pytest.fixture(scope="module")
def config_path(tmp_path_factory):
    ros = {"timeout_s": 1.0, "retries": 30, "discovery_wait_s": 60.0}  # 31 s for a restart under load
    return str(leaf_config_file(tmp_path_factory.mktemp("kill"), ros, "kill.yaml"))




def run_cli(config_path, domain, cwd: Path, bag: Path, kill: tuple[str, ...] = (),
            at_iteration: int = 0) -> tuple[int, dict, str]:
    """Run `bev-mdo optimize` (JSON on stdout, progress on stderr); SIGKILL the children whose command
    line names one of `kill` once the progress line of iteration `at_iteration` (0: the first) is printed;
    the recorder's only once it also has an iteration record on disk (a record printed can still be on its
    way to the recorder: the kill waits for that condition, never for a time). The JSON then gets
    `records_on_disk_at_kill`."""
    p = subprocess.Popen([PYTHON, "-m", "bev_mdo", "optimize", config_path, "--compose", "none", "--domain-id", str(domain), "--bag",
                          str(bag), "--json"], cwd=cwd, env=ros_env(domain), stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    err_lines = []
    killed = []
    deadline = time.monotonic() + 300
    for line in p.stderr:
        err_lines.append(line)
        if kill and not killed and line.startswith("iter") and int(line.split()[1]) >= at_iteration:
            # the readers at once; the recorder once it has an iteration record on disk
            for names in ([k for k in kill if k != "recorder"], [k for k in kill if k == "recorder"]):
                if names == ["recorder"]:
                    assert wait_until(lambda: _iterations_on_disk(bag) >= 1, 120.0), "no iteration record on disk"
                    on_disk = _iterations_on_disk(bag)
                for pid, cmd in child_processes(p.pid).items():
                    if any(f"{k}_node" in cmd for k in names):
                        os.kill(pid, signal.SIGKILL)  # a child of the run we started, by its id
                        killed.append(cmd)
            assert len(killed) == len(kill), killed
        if time.monotonic() > deadline:
            p.kill()
            break
    out = p.stdout.read()
    p.wait(timeout=60)
    result = json.loads(out) if out.strip() else {}
    if "recorder" in kill:
        result["records_on_disk_at_kill"] = on_disk
    return p.returncode, result, "".join(err_lines)


def _opens_without_repair(bag: Path) -> int:
    from mcap.reader import make_reader
    from rosbags.rosbag2 import Reader

    with Reader(bag) as reader:
        n_rosbags = sum(1 for _ in reader.messages())
        assert reader.message_count == n_rosbags
    files = sorted(bag.glob("*.mcap"))
    assert len(files) == 1
    with open(files[0], "rb") as f:
        r = make_reader(f)
        assert r.get_summary() is not None  # a finished file: summary present, no repair needed
        n_mcap = sum(1 for _ in r.iter_messages())
    assert n_mcap == n_rosbags > 0
    return n_mcap


def test_killing_a_reader_and_the_recorder_does_not_stall_or_loop(config_path, ros_domain, tmp_path):
    config = load_config(config_path)
    ref = run_optimization(config, InProcessEvaluator(resolve_disciplines(config)))
    rc0, base, err0 = run_cli(config_path, ros_domain, tmp_path, tmp_path / "calm")
    assert rc0 == 0, err0[-3000:]
    rc, out, err = run_cli(config_path, ros_domain, tmp_path, tmp_path / "killed", kill=("vehicle_mass", "recorder"))
    print(f"tail after the optimisation: undisturbed {base['tail_s']:.2f} s, with the kills {out.get('tail_s')} s")
    assert rc == 3, err[-3000:]
    for k, v in ref.design.items():
        assert out["design"][k] == pytest.approx(v, rel=1e-6), (k, out.get("discipline_errors"), err[-3000:])
    assert out["node_restarts"] == {"vehicle_mass": 1}
    assert "the recorder died" in out["recorder_failed"]
    assert err.count("warning: the recorder died") == 1
    assert "not restarted" in err and "BagError" not in err and "Traceback" not in err
    _opens_without_repair(tmp_path / "calm")
    _opens_without_repair(tmp_path / "killed")
    assert _iterations_on_disk(tmp_path / "killed") >= out["records_on_disk_at_kill"] >= 1  # none lost by the repair
    assert out["tail_s"] < 60  # bounded (the figure itself is measured in bench)
    # killed at the last iteration: in the tail, after (or during) the optimiser's last evaluation
    rc, late, err = run_cli(config_path, ros_domain, tmp_path, tmp_path / "late", kill=("vehicle_mass", "recorder"),
                            at_iteration=base["iterations"])
    print(f"tail with the kills at the last iteration: {late.get('tail_s')} s {late.get('tail_parts_s')}")
    assert rc == 3, err[-3000:]
    for k, v in ref.design.items():
        assert late["design"][k] == pytest.approx(v, rel=1e-6), k
    assert late["baseline"]["ok"] and late["baseline"]["outputs"] == base["baseline"]["outputs"]
    assert err.count("warning: the recorder died") == 1 and "Traceback" not in err
    _opens_without_repair(tmp_path / "late")
    assert _iterations_on_disk(tmp_path / "late") >= late["records_on_disk_at_kill"] >= 1
    assert late["tail_s"] < 60


def _iterations_on_disk(bag: Path) -> int:
    """Iteration records in the complete chunks of a bag being written (0 before its first chunk is on disk)."""
    from bev_mdo.bag.errors import BagError
    from bev_mdo.bag.reader import open_bag

    try:
        return open_bag(bag).counts.get("/bev_mdo/iteration", 0) if any(bag.glob("*.mcap")) else 0
    except BagError:
        return 0


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL, signal.SIGSTOP], ids=["SIGTERM", "SIGKILL", "SIGSTOP"])
def test_a_recorder_stopped_mid_run_is_named_and_its_bag_holds_what_it_wrote(config_path, ros_domain, tmp_path, sig):
    """The run's recorder is SIGTERMed (it closes its bag and exits 0) or SIGKILLed while the optimiser waits
    after its second iteration (test/cli/fault_optimizers.py, waiting-after-2) with three records on disk; the
    optimiser then goes on. The run ends with its result, one warning naming the stopped recorder and exit status
    3; the bag opens in rosbags and mcap as it is (after SIGKILL the run repaired it on the spot), holding the
    iteration records up to the last one the recorder wrote, in order, as the run printed them, and no later one.
    A recorder frozen by SIGSTOP is found stopped when the run ends, killed at once and named as frozen."""
    from rosbags.highlevel import AnyReader

    cli_tests = Path(__file__).resolve().parents[1] / "cli"
    env = {**ros_env(ros_domain), "PYTHONPATH": f"{cli_tests}{os.pathsep}{ros_env(ros_domain)['PYTHONPATH']}"}
    bag = tmp_path / "b"
    p = subprocess.Popen([PYTHON, str(cli_tests / "fault_optimizers.py"), "optimize", config_path, "--optimizer",
                          "waiting-after-2", "--domain-id", str(ros_domain), "--bag", str(bag), "--json"],
                         cwd=tmp_path, env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    try:
        err_lines = []
        for line in p.stderr:  # progress on stderr (--json): up to the second iteration, where the optimiser waits
            err_lines.append(line)
            if line.startswith("iter    2"):
                break
        assert err_lines and err_lines[-1].startswith("iter    2"), "".join(err_lines)[-3000:]
        while _iterations_on_disk(bag) < 3:  # the start point and two iterations flushed by the recorder
            assert p.poll() is None
            try:
                p.wait(timeout=0.05)
            except subprocess.TimeoutExpired:
                pass
        (recorder,) = [pid for pid, cmd in child_processes(p.pid).items() if "recorder_node" in cmd]
        os.kill(recorder, sig)  # a child of the run we started, by its id
        if sig == signal.SIGSTOP:
            assert wait_until(lambda: process_state(recorder) == "T")
        else:
            for line in p.stderr:  # the run's supervisor saw the recorder end (during the run, not at its end)
                err_lines.append(line)
                if line.startswith("[launcher] recorder exited"):
                    break
        p.stdin.write("go\n")
        p.stdin.close()
        bound = threading.Timer(300, p.kill)  # a run that hangs is ended, and then fails below
        bound.start()
        rest = p.stderr.read()  # what was read line by line stays read: not communicate()
        out = p.stdout.read()
        p.wait()
        bound.cancel()
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    err = "".join(err_lines) + rest
    assert p.returncode == 3 and "Traceback" not in err, err[-3000:]
    said = {signal.SIGTERM: "stopped (exit status 0) during the run", signal.SIGKILL: f"(exit status {-signal.SIGKILL}) during the run",
            signal.SIGSTOP: "the recorder was frozen (its process stopped, e.g. by SIGSTOP) at the end of the run"}[sig]
    assert err.count("warning: the recorder") == 1 and said in err, err[-3000:]
    doc = json.loads(out)
    assert doc["iterations"] == 4 and "the recorder" in doc["recorder_failed"]
    printed = [float(l.split()[3]) for l in err.splitlines() if l.startswith("iter ")]
    assert len(printed) == 5  # the start point and four iterations
    _opens_without_repair(bag)
    with AnyReader([bag]) as reader:
        conns = [c for c in reader.connections if c.topic == "/bev_mdo/iteration"]
        recs = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections=conns)]
    # the three records on disk when it stopped; no more were published before (the optimiser waited) and the
    # two after went to no recorder
    assert len(recs) == 3
    assert [int(r.sequence) for r in recs] == list(range(1, len(recs) + 1))
    assert [float(r.objective) for r in recs] == pytest.approx(printed[:len(recs)], abs=1e-6)
    # what the bag's readers tell agrees with the run's end-of-run record (answers.json, written beside the bag by
    # the run, not by the dead recorder): the records stop at iteration 2 of 4, the result is the run's
    from bev_mdo.bag.history import check_note, history, last_iterate
    from bev_mdo.bag.report import report

    checks: dict = {}
    assert len(history(bag, checks=checks)) == 3
    assert "the bag's iteration records stop at iteration 2 of the run's 4 (2 missing at the end" in check_note(checks)
    assert last_iterate(bag)[1:] == (doc["design"], 4)
    report(bag, tmp_path / "report")
    md = (tmp_path / "report" / "report.md").read_text()
    assert "## The run's result (iteration 4, from its end-of-run record)" in md
    assert f"{doc['mda_evaluations']} multidisciplinary evaluations (the run's total)" in md
