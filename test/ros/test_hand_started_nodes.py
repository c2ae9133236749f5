"""The coordinator and the recorder started by hand (docs/ros2-run.md) behave as the discipline nodes do: a
parameter they do not declare is one line and exit 2 (rclpy kept a misspelt ``-p formulaton:=idf`` without a
word), and SIGINT or SIGTERM ends them with one ``<node>: interrupted`` line, exit status 130 or 143 (the
coordinator exited 130 on both, silently)."""
from __future__ import annotations

import signal
import subprocess
import sys

import pytest

from bev_mdo.testing import ros_env

pytestmark = pytest.mark.ros
ROS_DOMAIN = 53
STARTING = "{}: starting (loading ROS 2 and the models)"


def _node(exe: str, *args: str, ros_domain: int, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "bev_mdo.ros.run", exe, *args], env=ros_env(ros_domain),
                          capture_output=True, text=True, timeout=120, **kw)


@pytest.mark.parametrize("param, words", [
    ("confg:=x.yaml", "parameter confg: coordinator_node has no such parameter; did you mean config?"),
    ("formulaton:=idf", "parameter formulaton: coordinator_node has no such parameter; did you mean formulation?"),
    ("vehicle.drag_area_m2:=0.6", "parameter vehicle.drag_area_m2: coordinator_node has no such parameter; it has "
                                  "compose, config, formulation, instances, optimizer, recorders, run_id"),
    ("instances:=enrgy=2", "-p instances: no discipline 'enrgy' in the config"),  # it named --instances
    ("instances:=0", "-p instances: 0 is outside 1..64")])
def test_a_parameter_the_coordinator_does_not_declare_or_a_bad_value_is_one_line_exit_2(ros_domain, leaf_config, param, words):
    p = _node("coordinator_node", "--ros-args", "-p", f"config:={leaf_config}", "-p", param, ros_domain=ros_domain)
    assert p.returncode == 2 and "Traceback" not in p.stderr, (p.returncode, p.stderr[-3000:])
    lines = p.stderr.strip().splitlines()  # (rclpy's own parameters come last in the list of those it has)
    assert len(lines) == 2 and lines[0] == STARTING.format("coordinator_node"), lines
    assert lines[1].startswith(f"coordinator_node: error: {words}"), lines


def test_a_parameter_the_recorder_does_not_declare_is_one_line_exit_2_and_no_bag(ros_domain, tmp_path):
    bag = tmp_path / "bag"
    p = _node("recorder_node", "--output", str(bag), "--ros-args", "-p", "qos_dept:=5", ros_domain=ros_domain)
    assert p.returncode == 2 and "Traceback" not in p.stderr, (p.returncode, p.stderr[-3000:])
    assert p.stderr.strip().splitlines() == [
        STARTING.format("recorder_node"),
        "recorder_node: error: parameter qos_dept: recorder_node has no such parameter; did you mean qos_depth?"]
    assert not bag.exists()


def _signalled(argv: list[str], ros_domain: int, sigint, ready, sig):
    """A node executable started with SIGINT at ``sigint`` (SIG_IGN: a shell's background job), sent ``sig`` once a
    line of its stderr is ``ready`` (or after 50 lines): (process, the lines read before, stdout, all of stderr)."""
    p = subprocess.Popen([sys.executable, "-m", "bev_mdo.ros.run", *argv], env=ros_env(ros_domain),
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, sigint))
    lines = []
    try:
        for line in p.stderr:
            lines.append(line)
            if ready(line) or len(lines) > 50:
                break
        p.send_signal(sig)
        out, rest = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    return p, lines, out, "".join(lines) + rest


@pytest.mark.parametrize("sig, status, sigint", [
    (signal.SIGINT, 130, signal.SIG_DFL), (signal.SIGTERM, 143, signal.SIG_DFL),
    (signal.SIGINT, 130, signal.SIG_IGN)], ids=["SIGINT", "SIGTERM", "SIGINT-ignored"])
def test_a_coordinator_signalled_while_it_waits_ends_with_one_line(ros_domain, leaf_config, sig, status, sigint):
    """Signalled while it waits for the disciplines (none run on this domain). SIGINT-ignored: started as a
    shell's background job, Python takes no SIGINT and only rclpy's own handler does (it shuts the context down)."""
    # its stderr ends if the coordinator dies; it says once a second what it waits for
    p, lines, out, err = _signalled(["coordinator_node", "--ros-args", "-p", f"config:={leaf_config}", "-p",
                                     "run_id:=by_hand_signalled"], ros_domain, sigint,
                                    lambda line: line.startswith("[start-up] waiting for discipline(s)"), sig)
    assert lines[-1].startswith("[start-up] waiting for discipline(s)"), err[-3000:]
    assert p.returncode == status and "Traceback" not in err and not out, (p.returncode, err[-3000:])
    assert err.strip().splitlines()[-1] == "coordinator_node: interrupted", err[-3000:]
    assert err.count("coordinator_node: interrupted") == 1


def test_a_recorder_started_as_a_background_job_ends_its_recording_on_sigint(ros_domain, tmp_path):
    """docs/ros2-run.md: SIGINT ends a serving recorder's recording. Started by a script as a `&` job (SIGINT
    ignored), it went on recording; `kill -INT` to the coordinator of the same script raised from its publisher
    ("publisher's context is invalid"), exit 1. A node executable now takes SIGINT whoever ignored it."""
    bag = tmp_path / "bag"
    p, _, _, err = _signalled(["recorder_node", "--output", str(bag)], ros_domain, signal.SIG_IGN,
                              lambda line: "recording to" in line, signal.SIGINT)
    assert p.returncode == 0 and "Traceback" not in err, (p.returncode, err[-3000:])
    assert err.strip().splitlines()[-1] == (f"recorded 0 messages to {bag / 'bag_0.mcap'}; no iteration record came "
                                            "(a pareto run sends none; a coordinator started without -p recorders:=1 "
                                            "may have sent its records before this recorder matched its topics)"), \
        err[-3000:]


def test_the_recorder_reads_a_relative_key_from_the_configs_folder(tmp_path, monkeypatch):
    """README: relative paths count from the config's folder, and the discipline nodes and the coordinator
    read the key so; the recorder read it from its working directory ('cannot read', exit 2, and the
    coordinator gave up after 30 s: 'the run's recorder did not declare itself')."""
    from bev_mdo.protocol.signing import Signer
    from bev_mdo.ros.recorder_node import _signer_of

    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "sign.key").write_bytes(b"k" * 32)
    (tmp_path / "run" / "sign.key").chmod(0o600)
    monkeypatch.chdir(tmp_path)  # not the config's folder
    signer = _signer_of("ros: {sign_key_file: sign.key}\n", tmp_path / "run")
    assert isinstance(signer, Signer)
    assert _signer_of("ros: {}\n", tmp_path / "run") is None



def test_status_shows_each_process_of_one_node_name_its_own_fingerprint(ros_domain, leaf_config, tmp_path,
                                                                         rclpy_context):
    """Two acceleration_node processes (one node name) of two configs: status showed the fingerprint of the
    declaration last received under the name on both rows (one declaration slot per instance name)."""
    import rclpy
    import yaml

    from bev_mdo import binding
    from bev_mdo.config import RunConfig
    from bev_mdo.launcher import Launcher
    from bev_mdo.processes import discipline_argv
    from bev_mdo.ros.fastwait import until
    from bev_mdo.ros.status import collect
    from bev_mdo.testing import REPO

    raw = yaml.safe_load((REPO / "config" / "leaf_epa_combined.yaml").read_text())
    raw["ros"] = {"domain_id": ros_domain}
    epa = tmp_path / "epa.yaml"
    epa.write_text(yaml.safe_dump(raw, sort_keys=False))
    fps = {label: binding.fingerprint(RunConfig.load(str(path)), "acceleration")[0]
           for label, path in (("nedc", leaf_config), ("epa", epa))}
    assert fps["nedc"] != fps["epa"]
    node = rclpy.create_node("status_fingerprints", context=rclpy_context)
    rows: list[dict] = []
    with Launcher(ros_env(ros_domain), log_dir=tmp_path / "logs") as launcher:
        for label, path in (("nedc", leaf_config), ("epa", epa)):
            launcher.add(label, discipline_argv("acceleration", str(path)), restart=False)
        pids = {launcher.node(label).proc.pid: label for label in fps}

        def both() -> bool:
            rows[:] = [r for r in collect(node, 0.5) if r["discipline"] == "acceleration" and r["pid"] in pids]
            return len(rows) == 2
        try:
            assert until(both, 120.0, lambda: None), rows
        finally:
            node.destroy_node()
    assert {r["pid"]: r["fingerprint"] for r in rows} == {pid: fps[label] for pid, label in pids.items()}, rows
    assert {r["instance"] for r in rows} == {"acceleration_node"} and {r["run_id"] for r in rows} == {"standalone"}


def test_a_coordinator_names_the_node_that_serves_another_run(ros_domain, leaf_config, tmp_path, rclpy_context):
    """An energy node started with -p run_id:=otherrun: the start-up of run r3 gave up with "discipline(s)
    ['energy'] not found on ROS domain" and asked whether the node was running, which it was."""
    import rclpy

    from bev_mdo.config import load_config
    from bev_mdo.launcher import Launcher
    from bev_mdo.processes import discipline_argv
    from bev_mdo.ros.evaluator import DisciplineMissing, RosEvaluator
    from bev_mdo.ros.status import NodeStatsListener

    node = rclpy.create_node("r3_coordinator", context=rclpy_context)
    with Launcher(ros_env(ros_domain), log_dir=tmp_path / "logs") as launcher:
        launcher.add("energy", discipline_argv("energy", str(leaf_config), run_id="otherrun"), restart=False)
        stats = NodeStatsListener(node)
        try:  # the node is up (its counters come after its declaration)
            assert stats.wait(lambda s: s.seen("energy"), 120.0)
        finally:
            stats.close()
        ev = RosEvaluator(node, run_id="r3", config=load_config(leaf_config))
        try:
            with pytest.raises(DisciplineMissing) as err:
                ev.wait_for_disciplines(["energy"], wait_s=5.0)
        finally:
            ev.close()
            node.destroy_node()
    assert "['energy'] not found on ROS domain" in str(err.value)
    assert "'energy' serves run(s) ['otherrun'] only, not run 'r3' (a node started with -p run_id:=R" in str(err.value)


@pytest.mark.parametrize("param, owner", [("discipline:=range", "discipline_node"),
                                          ("disciplines:=range,cost", "composed_node")])
def test_a_discipline_executable_refuses_another_nodes_parameter(ros_domain, leaf_config, param, owner):
    """energy_node -p discipline:=range started and served 'range': the discipline parameter is discipline_node's."""
    p = _node("energy_node", "--ros-args", "-p", f"config:={leaf_config}", "-p", param, ros_domain=ros_domain)
    assert p.returncode == 2 and "Traceback" not in p.stderr, (p.returncode, p.stderr[-3000:])
    assert p.stderr.strip().splitlines() == [
        STARTING.format("energy_node"),
        f"energy_node: error: parameter {param.split(':=')[0]}: energy_node has no such parameter; it is {owner}'s"]
