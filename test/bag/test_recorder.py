"""recorder_node end to end: separate publisher process, clean stop, SIGKILL and repair."""
from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from bev_mdo.testing import ros_env

from .conftest import ROOT

pytestmark = [pytest.mark.ros, pytest.mark.slow]
DOMAIN = 43
HERE = Path(__file__).parent


def _start_recorder(bag: Path, *extra: str) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "bev_mdo.ros.run", "recorder_node", "--output", str(bag), *extra,
           "--ros-args", "-p", "flush_period_s:=0.1", "-p", "discovery_period_s:=0.1"]
    # SIGINT at its default in the child: a suite started as a shell's background job inherits it ignored
    return subprocess.Popen(cmd, env=ros_env(DOMAIN), cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def _start_publisher(batch: int, n_batches: int) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, str(HERE / "_publisher.py"), str(batch), str(n_batches)],
                            env=ros_env(DOMAIN), cwd=ROOT, stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)


def _expect(proc: subprocess.Popen, line: str) -> None:
    got = proc.stdout.readline().strip()
    assert got == line, f"expected {line!r}, got {got!r}"


def _send(pub: subprocess.Popen, expected_total: int) -> None:
    pub.stdin.write("go\n")
    pub.stdin.flush()
    _expect(pub, f"sent {expected_total}")


def _wait_recorded(bag: Path, count: int, timeout_s: float = 30.0):
    """Poll the growing bag until its complete chunks hold ``count`` messages."""
    from bev_mdo.bag.errors import BagError
    from bev_mdo.bag.reader import open_bag

    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            opened = open_bag(bag)
            if opened.message_count >= count:
                return opened
        except BagError:
            pass  # header or first chunk not flushed yet
        time.sleep(0.05)
    raise AssertionError(f"{bag}: fewer than {count} messages recorded after {timeout_s} s")


def _values(bag):
    return [(int(o.sequence), float(o.objective), [float(v) for v in o.design.values])
            for _m, o in bag.decoded()]


def _published(n: int):
    return [(i, 1000.0 - i, [50.0 + 0.25 * i, 40.0 + 0.5 * i]) for i in range(n)]


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_recorder_clean_stop_records_everything(tmp_path, sig):
    """Stopped by SIGINT or SIGTERM (how a recording ends, as Ctrl-C ends `ros2 bag record`), the recorder closes
    its bag with every message, says so in its last line and exits 0 (docs/recording.md)."""
    from rosbags.highlevel import AnyReader

    from bev_mdo.bag.reader import open_bag, read_config

    config = tmp_path / "run.yaml"
    config.write_text("optimizer: SLSQP\n")
    bag = tmp_path / "clean"
    rec = _start_recorder(bag, "--config", str(config), "--run-id", "rec-test")
    pub = _start_publisher(250, 2)
    try:
        _expect(pub, "ready")
        _send(pub, 250)
        _send(pub, 500)
        rec.send_signal(sig)
        err = rec.communicate(timeout=60)[1]
    finally:
        for proc in (pub, rec):
            proc.kill()
            proc.wait()
    lines = err.strip().splitlines()
    assert rec.returncode == 0 and "Traceback" not in err, (rec.returncode, err[-2000:])
    assert lines[-1].startswith("recorded 500 messages to "), lines
    history = subprocess.run([sys.executable, "-m", "bev_mdo", "history", str(bag), "--csv", "-"], cwd=tmp_path,
                             env=ros_env(DOMAIN), capture_output=True, text=True, timeout=120)
    assert history.returncode == 0 and len(history.stdout.strip().splitlines()) == 501, history.stderr[-2000:]
    opened = open_bag(bag)
    assert not opened.truncated and (bag / "metadata.yaml").is_file()
    assert _values(opened) == _published(500)
    # stored with its folder (and the recorder's) as search_path, as the nodes read it (recorded_text)
    assert yaml.safe_load(read_config(opened)) == {"optimizer": "SLSQP", "search_path": [str(tmp_path.resolve()),
                                                                                          str(ROOT.resolve())]}
    assert opened.info["run_id"] == "rec-test"
    with AnyReader([bag]) as reader:
        assert reader.message_count == 500
        assert [c.topic for c in reader.connections] == ["/bev_mdo/iteration"]


def test_recorder_stores_a_relative_config_resolved(tmp_path, monkeypatch):
    """A recorder started by hand with a config named relative to its folder stored the file's text: a config
    without search_path (its modules beside it, found by the nodes), so `bev-mdo report` run from another folder
    could not load its disciplines and gave a report without units or answers, silently."""
    from bev_mdo.bag.reader import open_bag, read_config
    from bev_mdo.config import RunConfig

    bag = tmp_path / "by_hand"
    rec = _start_recorder(bag, "--config", "examples/sellar/sellar_mdf.yaml", "--run-id", "by_hand")  # cwd: ROOT
    try:
        deadline = time.monotonic() + 60
        while not any(bag.glob("*.mcap")) and rec.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)  # the bag is made once the config is read
        rec.send_signal(signal.SIGINT)
        err = rec.communicate(timeout=60)[1]
    finally:
        rec.kill()
        rec.wait()
    assert rec.returncode == 0, err[-2000:]
    stored = yaml.safe_load(read_config(open_bag(bag)))
    assert str(ROOT / "examples" / "sellar") in stored["search_path"]
    monkeypatch.chdir(tmp_path)  # a reader elsewhere loads its disciplines (sellar_disciplines.py) from there
    assert RunConfig.load(stored).names == ("sellar1", "sellar2", "sellar_obj")


def test_sigkill_leaves_readable_prefix_and_repair_restores(tmp_path):
    from rosbags.highlevel import AnyReader

    from .conftest import cli

    bag = tmp_path / "killed"
    rec = _start_recorder(bag)
    pub = _start_publisher(300, 3)
    try:
        _expect(pub, "ready")
        _send(pub, 300)
        _wait_recorded(bag, 300)           # first batch flushed to disk
        pub.stdin.write("go\n")            # second batch in flight while the recorder dies
        pub.stdin.flush()
        rec.send_signal(signal.SIGKILL)
        rec.wait(timeout=30)
    finally:
        for proc in (pub, rec):
            proc.kill()
            proc.wait()
    assert not (bag / "metadata.yaml").exists()
    from bev_mdo.bag.reader import open_bag

    opened = open_bag(bag)
    assert opened.truncated
    values = _values(opened)
    assert len(values) >= 300 and values == _published(len(values))

    code, out, err = cli("bag", "repair", str(bag))
    assert code == 0, err
    repaired = open_bag(bag)
    assert not repaired.truncated and _values(repaired) == values
    with AnyReader([bag]) as reader:
        assert reader.message_count == len(values)
