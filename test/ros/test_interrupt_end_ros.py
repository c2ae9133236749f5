"""Ctrl-C at the end of an `optimize` over ROS, after the recorder closed its bag and before the result is stored
with it (the run's summary: drops, restarts, a recorder that died): it ended with a bare `bev-mdo: interrupted`,
though the bag held every iteration, while a signal a moment earlier (the nodes being stopped) or later (the
answers being made) named the bag and what it holds. Now every step after the run has its bag does. The
signal is raised in process from the step (no timing)."""
from __future__ import annotations

from pathlib import Path

from bev_mdo.bag.history import ITERATION_TOPIC
from bev_mdo.bag.reader import open_bag
from bev_mdo.cli import main

ROS_DOMAIN = 221
LEAF = str(Path(__file__).resolve().parents[2] / "config" / "leaf_nedc.yaml")


def test_a_signal_after_the_recorder_closed_the_bag_names_it(tmp_path, monkeypatch, capsys, ros_domain):
    def ctrl_c(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr("bev_mdo.sessions.OptimizeRosSession.summary", ctrl_c)
    bag = tmp_path / "bag"
    assert main(["optimize", LEAF, "--bag", str(bag), "--quiet", "--domain-id", str(ros_domain)]) == 130
    err = capsys.readouterr().err.strip().splitlines()
    records = sum(1 for _ in open_bag(bag).messages([ITERATION_TOPIC]))
    assert records > 0
    assert err[-2:] == ["bev-mdo: interrupted", f"bev-mdo: bag {bag}: {records} iteration records, every finished "
                        f"iteration (bev-mdo history {bag}; bev-mdo resume {bag} goes on from the last)"], err[-5:]
