"""A node says it is starting before the slow imports (they were silent for 2-3 s)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from bev_mdo.testing import REPO, ros_env

pytestmark = pytest.mark.ros


def _stop(p: subprocess.Popen) -> None:
    p.terminate()
    try:
        p.wait(timeout=30)
    except subprocess.TimeoutExpired:
        p.kill()
        p.wait()


def test_a_node_announces_itself_before_loading_ros(ros_domain):
    p = subprocess.Popen([sys.executable, "-m", "bev_mdo.ros.run", "cost_node", "--ros-args", "-p",
                          f"config:={REPO / 'config' / 'leaf_nedc.yaml'}"],
                         env=ros_env(ros_domain), stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)
    try:
        first = p.stderr.readline()
    finally:
        _stop(p)
    assert first.startswith("cost_node: starting"), first


def test_a_node_bound_to_an_all_digit_run_id_serves_it(ros_domain):
    """A run id of hex digits that happen to be decimal ("12345678") reaches the node as a string
    (an unquoted -p run_id:=12345678 was parsed as an integer and the node died)."""
    from bev_mdo.processes import discipline_argv

    argv = discipline_argv("cost", str(REPO / "config" / "leaf_nedc.yaml"), run_id="12345678")
    lines = _until_serving(argv, ros_domain, "cost")
    assert any("bound to run 12345678" in line for line in lines), "".join(lines)[-2000:]


def _until_serving(argv, ros_domain, name: str) -> list[str]:
    """The node's stderr lines until it serves `name` (or dies, or 50 lines); the node is then stopped."""
    p = subprocess.Popen(argv, env=ros_env(ros_domain), stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)
    lines = []
    try:
        for line in p.stderr:  # ends when the node dies; the node says "serving ..." once it is up
            lines.append(line)
            if f"serving '{name}'" in line or len(lines) > 50:
                break
    finally:
        _stop(p)
    return lines


def test_a_node_whose_teardown_hangs_in_c_ends_at_its_bound(ros_domain):
    """A node told to stop (SIGTERM: what the kernel sends a launched node whose parent died) whose
    teardown blocks in C, holding Python's lock as a Fast DDS destroy that never returns does, ends at
    its teardown bound (here 1 s) with every thread's stack on stderr, instead of living on alone."""
    import signal

    code = "\n".join([
        "import ctypes, functools, sys",
        "import bev_mdo.ros.discipline_node as dn",
        "from bev_mdo import stacks",
        "dn.deadline = functools.partial(stacks.deadline, 1.0)",
        "dn.DisciplineNode.destroy_node = lambda self: ctypes.PyDLL(None).sleep(120)",
        "_serve = dn.serve",  # says when the node is built and serving (a SIGTERM before ends it at once)
        "dn.serve = lambda node: (print('in serve', file=sys.stderr, flush=True), _serve(node))",
        f"sys.exit(dn.main(['--ros-args', '-p', 'config:={REPO / 'config' / 'leaf_nedc.yaml'}'], discipline='cost'))"])
    p = subprocess.Popen([sys.executable, "-c", code], cwd=REPO, env=ros_env(ros_domain), stderr=subprocess.PIPE,
                         stdout=subprocess.DEVNULL, text=True)
    lines = []
    try:
        for line in p.stderr:
            lines.append(line)
            if line.startswith("in serve") or len(lines) > 50:
                break
        p.send_signal(signal.SIGTERM)
        rest = p.communicate(timeout=60)[1]
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    assert lines and lines[-1].startswith("in serve"), "".join(lines)[-2000:]
    assert p.returncode == -signal.SIGALRM, (p.returncode, rest[-2000:])
    assert "Timeout" in rest and "<lambda>" in rest  # the stack of the blocked teardown


# A signal to the process itself at a known point of its loading, as when a run is stopped while its nodes
# still load (eight runs on two cores): "import", the moment the node's module is imported (Python's own
# SIGTERM default, before: a silent 143); "build", while the node builds its discipline, after rclpy.init
# installed its handlers (before: a silent 0). Delivered by the process itself, never by a timed kill.
_INTERRUPTED = """
import os, signal, sys
exe, phase, sig = sys.argv[1], sys.argv[2], getattr(signal, sys.argv[3])
class Hook:
    def find_spec(self, name, path=None, target=None):
        if phase == 'import' and name == 'bev_mdo.ros.' + ('recorder_node' if exe == 'recorder_node' else 'discipline_node'):
            os.kill(os.getpid(), sig)
        return None
sys.meta_path.insert(0, Hook())
if phase == 'build':
    import bev_mdo.ros.discipline_node as dn
    build = dn._build
    dn._build = lambda config, name: (os.kill(os.getpid(), sig), build(config, name))[1]
from bev_mdo.ros.run import run
sys.exit(run(exe, sys.argv[4:]))
"""


@pytest.mark.parametrize("exe, phase, sig, status", [
    ("recorder_node", "import", "SIGINT", 130), ("energy_node", "import", "SIGTERM", 143),
    ("energy_node", "build", "SIGINT", 130), ("energy_node", "build", "SIGTERM", 143)])
def test_a_node_interrupted_while_loading_ends_with_one_line(exe, phase, sig, status, ros_domain, tmp_path):
    """docs/recording.md: one '<node>: interrupted' line, status 130 (143 for SIGTERM)."""
    args = [] if exe == "recorder_node" else ["--ros-args", "-p", f"config:={REPO / 'config' / 'leaf_nedc.yaml'}"]
    p = subprocess.run([sys.executable, "-c", _INTERRUPTED, exe, phase, sig, *args], env=ros_env(ros_domain),
                       cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert p.returncode == status and "Traceback" not in p.stderr, (p.returncode, p.stderr[-2000:])
    assert p.stderr.strip().splitlines() == [f"{exe}: starting (loading ROS 2 and the models)", f"{exe}: interrupted"]


@pytest.mark.parametrize("param, words", [
    ("vehicle.drag_aera_m2:=0.6", "parameter vehicle.drag_aera_m2: energy_node has no such parameter; "
                                  "did you mean vehicle.drag_area_m2?"),
    ("cnfig:=x.yaml", "parameter cnfig: energy_node has no such parameter; did you mean config?"),
    ("vehicle.aux_power_w:=400", "it overrides only the vehicle values its config sets"),
    # docs/ros2-run.md offered -p instance:= for a second instance; the coordinator, which finds instances by
    # node name, then said "7 of 7 declared" and "not found on ROS domain" (exit 6)
    ("instance:=energy_b", "does not rename the node (the coordinator looks for its name): start it with "
                           "-r __node:=energy_b or bev-mdo node energy --instance")])
def test_a_parameter_the_node_does_not_declare_is_one_line_exit_2(ros_domain, param, words):
    """rclpy keeps an undeclared override without a word: a misspelt vehicle.drag_aera_m2 left the node
    serving the config's drag area, with the unchanged fingerprint."""
    p = subprocess.run([sys.executable, "-m", "bev_mdo.ros.run", "energy_node", "--ros-args", "-p",
                        f"config:={REPO / 'config' / 'leaf_nedc.yaml'}", "-p", param],
                       env=ros_env(ros_domain), capture_output=True, text=True, timeout=120)
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and "Traceback" not in p.stderr and len(lines) == 2, p.stderr[-3000:]
    assert lines[-1] == f"energy_node: error: {words}" or lines[-1].endswith(words), lines


def test_a_node_without_a_config_says_it_serves_the_default_one(ros_domain):
    """Every node in docs/ros2-run.md is started with -p config:=FILE; one started without served the
    shipped config without a word."""
    lines = _until_serving([sys.executable, "-m", "bev_mdo.ros.run", "cost_node"], ros_domain, "cost")
    said = [line for line in lines if "no -p config:=FILE given" in line]
    assert len(said) == 1 and "serving the default run config" in said[0] and said[0].rstrip().endswith(
        str(Path("config") / "leaf_nedc.yaml")), "".join(lines)[-2000:]
    assert any("serving 'cost'" in line for line in lines)


@pytest.mark.parametrize("instance", ["a b", "a-b", "x/y", "é"])
def test_an_instance_name_a_node_name_cannot_hold_is_one_line_exit_2(instance, capsys):
    """It used to reach rcl as a remap rule and stop with a raw RCLError, exit 7."""
    from bev_mdo.cli import main

    assert main(["node", "energy", "--instance", instance, "--config", str(REPO / "config" / "leaf_nedc.yaml")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "use only letters, digits and _" in err[0], err


@pytest.mark.parametrize("param, words", [
    ("vehicle.drag_area_m2:=big", "parameter vehicle.drag_area_m2: 'big' is STRING, expected DOUBLE"),
    ("config:=42", "parameter config: 42 is INTEGER, expected STRING (quote it"),
    ("instance:=[1,2]", "parameter instance: [1, 2] is INTEGER_ARRAY, expected STRING")])
def test_a_parameter_of_the_wrong_type_is_one_line_exit_2(ros_domain, param, words):
    """rclpy's InvalidParameterTypeException stopped the node with a 26-line traceback, exit 1."""
    p = subprocess.run([sys.executable, "-m", "bev_mdo.ros.run", "energy_node", "--ros-args", "-p",
                        f"config:={REPO / 'config' / 'leaf_nedc.yaml'}", "-p", param],
                       env=ros_env(ros_domain), capture_output=True, text=True, timeout=120)
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and "Traceback" not in p.stderr and len(lines) <= 2, p.stderr[-3000:]
    assert words in lines[-1], lines


def test_a_recorder_parameter_of_the_wrong_type_is_one_line_exit_2(ros_domain, tmp_path):
    p = subprocess.run([sys.executable, "-m", "bev_mdo.ros.run", "recorder_node", "--output", str(tmp_path / "b"),
                        "--ros-args", "-p", "qos_depth:=deep"],
                       env=ros_env(ros_domain), capture_output=True, text=True, timeout=120)
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and "Traceback" not in p.stderr and len(lines) <= 2, p.stderr[-3000:]  # "starting", the error
    assert "recorder_node: error: parameter qos_depth: 'deep' is STRING, expected INTEGER" in lines[-1], lines


def test_a_whole_number_for_a_vehicle_value_is_that_number(ros_domain):
    """-p vehicle.drag_area_m2:=1 (an INTEGER to ROS) is 1.0, not a type error."""
    lines = _until_serving([sys.executable, "-m", "bev_mdo.ros.run", "energy_node", "--ros-args", "-p",
                            f"config:={REPO / 'config' / 'leaf_nedc.yaml'}", "-p", "vehicle.drag_area_m2:=1"],
                           ros_domain, "energy")
    assert any("serving 'energy'" in line for line in lines), "".join(lines)[-2000:]


@pytest.mark.parametrize("extra, name", [([], "cost_node"), (["-r", "__node:=mine"], "mine")])
def test_the_generic_node_is_named_after_its_discipline(ros_domain, extra, name):
    """Two user disciplines under discipline_node, started as docs/ros2-run.md writes it, were both named
    discipline_node: `status` listed each process under both disciplines and warned of one instance."""
    code = "\n".join([
        "import sys", "import bev_mdo.ros.discipline_node as dn",
        "dn.serve = lambda node: print('named', node.get_name(), node.instance, file=sys.stderr, flush=True)",
        "sys.exit(dn.main(sys.argv[1:]))"])
    p = subprocess.run([sys.executable, "-c", code, "--ros-args", "-p", f"config:={REPO / 'config' / 'leaf_nedc.yaml'}",
                        "-p", "discipline:=cost", *extra], cwd=REPO, env=ros_env(ros_domain), capture_output=True,
                       text=True, timeout=120)
    assert p.returncode == 0 and f"named {name} /{name}\n" in p.stderr, p.stderr[-2000:]


HINT_P = " (a parameter is -p name:=value, e.g. -p config:=my.yaml; an empty text is -p \"name:=''\")"


@pytest.mark.parametrize("exe, bad, said", [
    ("energy_node", ["-p", "config=config/leaf_nedc.yaml"], "Couldn't parse parameter override rule: "
                                                            "'-p config=config/leaf_nedc.yaml'. Error: Expected lexeme"),
    ("energy_node", ["-p", "instance:="], "Couldn't parse parameter override rule: '-p instance:='" + HINT_P),
    ("coordinator_node", ["-p"], "Couldn't parse trailing -p flag. No parameter override rule found." + HINT_P),
    # the review: rcl's reason kept, no -p hint for what is no -p
    ("energy_node", ["--params-file", "LIST"], "Couldn't parse params file: '--params-file LIST'. Error: Sequences "
                                               "cannot be key at line 1"),
    ("energy_node", ["--log-level", "bogus"], "Couldn't parse log level: '--log-level bogus'. Error: Argument does "
                                              "not use a valid severity level")])
def test_ros_args_rcl_cannot_parse_are_one_line_and_status_2(ros_domain, tmp_path, exe, bad, said):
    """docs/ros2-run.md's `-p instance:=`, or `-p config=FILE` for config:=, was rcl's traceback and status 1."""
    listed = tmp_path / "list.yaml"
    listed.write_text("- a\n- b\n")
    bad, said = [str(listed) if b == "LIST" else b for b in bad], said.replace("LIST", str(listed))
    p = subprocess.run([sys.executable, "-m", "bev_mdo.ros.run", exe, "--ros-args", *bad], cwd=REPO,
                       env=ros_env(ros_domain), capture_output=True, text=True, timeout=120)
    ours = [line for line in p.stderr.splitlines() if not line.startswith("[ERROR]")]  # rcl's own log line
    assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr[-2000:]
    assert ours[-1].startswith(f"{exe}: error: --ros-args: {said}") and ", at /" not in ours[-1], ours
    assert (HINT_P in ours[-1]) == ("-p" in bad), ours
