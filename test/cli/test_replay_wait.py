"""`bev-mdo replay` waits for a subscriber on each topic by default (a recorder started beside it
then misses nothing), gives up after --wait-timeout with one line, and --no-wait publishes at once."""
from __future__ import annotations

import subprocess
import sys

from bev_mdo.cli import main
from bev_mdo.testing import REPO, ros_env


def _bag(tmp_path):
    out = tmp_path / "sweep"
    assert main(["sweep", str(REPO / "config" / "leaf_nedc.yaml"), "--doe", "lhs", "--samples", "3",
                 "--out", str(out), "--no-plots", "--transport", "inprocess"]) == 0
    return out / "bag"


def _replay(bag, ros_domain, *extra):
    return subprocess.run([sys.executable, "-m", "bev_mdo", "replay", str(bag), "--as-fast-as-possible", *extra],
                          env=ros_env(ros_domain), capture_output=True, text=True, timeout=120)


def test_replay_waits_by_default_and_says_so_then_gives_up(ros_domain, tmp_path):
    p = _replay(_bag(tmp_path), ros_domain, "--wait-timeout", "0.5")
    assert p.returncode == 2
    err = p.stderr.strip().splitlines()
    assert err[0].endswith("bag: records are not signed (its signing record says so); they are read unverified")
    assert err[1].startswith("waiting up to 0.5 s for 1 subscriber(s) on each topic (--no-wait publishes at once)")
    assert "fewer than 1 subscriber(s) on /bev_mdo/" in err[-1] and "after 0.5 s" in err[-1]  # names the topics


def test_no_wait_publishes_at_once(ros_domain, tmp_path):
    p = _replay(_bag(tmp_path), ros_domain, "--no-wait")
    assert p.returncode == 0, p.stderr
    assert "waiting" not in p.stderr and p.stdout.startswith("replayed 3 messages")


def test_nothing_to_replay_is_said_and_exits_1(ros_domain, tmp_path):
    """A malformed-files trial: a bag cut before its first chunk ended "replayed 0 messages", exit 0."""
    from bev_mdo.bag.errors import BagError
    from bev_mdo.bag.reader import open_bag

    bag = _bag(tmp_path)
    mcap = next(bag.glob("*.mcap"))
    data, cut = mcap.read_bytes(), tmp_path / "cut"
    cut.mkdir()
    for k in range(1, 50):  # the first cut that still opens (its header whole) with no message in it
        (cut / mcap.name).write_bytes(data[:len(data) * k // 50])
        try:
            if open_bag(cut).message_count == 0:
                break
        except BagError:
            continue
    else:
        raise AssertionError("no cut of the bag opens with no message")
    p = _replay(cut, ros_domain, "--no-wait")
    assert p.returncode == 1 and p.stdout.startswith("replayed 0 messages"), p.stderr
    assert p.stderr.strip().splitlines()[-1] == f"bev-mdo replay: {cut}: nothing to replay"
