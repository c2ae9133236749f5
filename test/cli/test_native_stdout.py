"""stdout belongs to bev-mdo: what native libraries print (Fast DDS logs errors with std::cout)
goes to stderr, so ``--json`` stays parseable for a pipe reader (a Fast DDS
``[RTPS_TRANSPORT_SHM Error]`` line once came before a run's JSON)."""
from __future__ import annotations

import json
import subprocess

from bev_mdo.testing import PYTHON, REPO, ros_env

SNIPPET = """
import ctypes, os, sys
from bev_mdo.cli import native_output_to_stderr
native_output_to_stderr()
libc = ctypes.CDLL(None)
libc.puts(b"native puts")        # C stdio on descriptor 1
libc.fflush(None)
os.write(1, b"native write\\n")   # raw descriptor 1
print('{"ok": 1}')
"""


def test_native_writes_to_descriptor_1_go_to_stderr_and_print_to_stdout():
    p = subprocess.run([PYTHON, "-c", SNIPPET], cwd=REPO, capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    assert json.loads(p.stdout) == {"ok": 1}
    assert "native puts" in p.stderr and "native write" in p.stderr


def test_stdout_into_a_pipe_is_written_line_by_line():
    """Progress lines came at the end of an optimisation whose stdout went to a file or a pipe (block-buffered):
    the first line is read while the process still waits to write its second."""
    snippet = ("import sys\nfrom bev_mdo.cli import native_output_to_stderr\nnative_output_to_stderr()\n"
               "print('iteration 1')\nsys.stdin.readline()\nprint('iteration 2')\n")
    p = subprocess.Popen([PYTHON, "-c", snippet], cwd=REPO, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        import select

        # buffered, nothing comes until the process ends, and it waits for our line: a bound, not a timing
        assert select.select([p.stdout], [], [], 120)[0], "the first line did not come before the process's end"
        assert p.stdout.readline() == "iteration 1\n"
        p.stdin.write("go\n")
        p.stdin.flush()
        assert p.stdout.readline() == "iteration 2\n"
    finally:
        p.kill()
        p.wait(timeout=60)


def test_fast_dds_errors_do_not_corrupt_json(ros_domain, tmp_path):
    """A profile file Fast DDS cannot parse makes it print two XMLPARSER errors on std::cout in
    every process; `evaluate --json` over ROS (its own nodes) still prints one JSON document on stdout."""
    bad = tmp_path / "bad_profile.xml"
    bad.write_text("<bad")
    env = ros_env(ros_domain)
    env["FASTRTPS_DEFAULT_PROFILES_FILE"] = str(bad)
    p = subprocess.run([PYTHON, "-m", "bev_mdo", "evaluate", str(REPO / "config" / "leaf_nedc.yaml"),
                        "--transport", "ros", "--json", "--domain-id", str(ros_domain)], cwd=tmp_path, env=env, capture_output=True,
                       text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-3000:]
    assert "XMLPARSER" in p.stderr  # the native error was printed, on stderr
    out = json.loads(p.stdout)
    assert set(out["design"]) and out["outputs"]["energy_wh_per_km"] > 0
