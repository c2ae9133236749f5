"""A run started as a shell's background job (``bev-mdo optimize ... &`` in a script) inherits SIGINT ignored, and
so did every node it started: Launcher.stop's SIGINT reached none of them, and each was stopped 30 s (the recorder)
or 5 s later by SIGUSR1, which wrote a stack dump into its log, then SIGTERM. The launcher starts its nodes with
SIGINT and SIGTERM at their defaults: the recorder closes its bag at the first signal and no log holds a stack dump.
"""
from __future__ import annotations

import json
import resource
import signal
import subprocess

from bev_mdo.testing import PYTHON, leaf_config_file, ros_env


def _as_a_background_job() -> None:  # what `cmd &` in a non-interactive shell does to the job (no `timeout` wrapper:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # it handles SIGINT, so its child starts with SIGINT at its default)
    resource.setrlimit(resource.RLIMIT_AS, (4_000_000 * 1024, 4_000_000 * 1024))  # ulimit -v 4000000


def test_a_run_with_sigint_ignored_stops_its_nodes_at_the_first_signal(ros_domain, tmp_path):
    config = leaf_config_file(tmp_path, {"discovery_wait_s": 60.0})
    bag = tmp_path / "bag"
    p = subprocess.run([PYTHON, "-m", "bev_mdo", "optimize", str(config), "--compose", "none", "--domain-id",
                        str(ros_domain), "--bag", str(bag), "--json"], cwd=tmp_path, env=ros_env(ros_domain),
                       capture_output=True, text=True, preexec_fn=_as_a_background_job, timeout=600)
    assert p.returncode == 0, p.stderr[-3000:]
    assert json.loads(p.stdout)["feasible"]
    logs = sorted((bag / "logs").glob("*.log"))
    assert {"recorder.log", "energy.log"} <= {f.name for f in logs}
    for log in logs:  # SIGUSR1's dump (faulthandler): a node that outlived the launcher's SIGINT
        text = log.read_text(errors="replace")
        assert "most recent call first" not in text, f"{log.name}:\n{text[-3000:]}"
    recorder = (bag / "logs" / "recorder.log").read_text().splitlines()
    assert recorder[-1].startswith("recorded "), recorder[-5:]  # closed its bag at SIGINT and said so, last
    assert "warning" not in p.stderr, p.stderr[-3000:]
