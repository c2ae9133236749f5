"""The end of a ROS run waits for no dead node: when the coordinator's final wait for
acknowledgements may stop (sessions.acks_needless) and Launcher.died_within, without processes."""
from __future__ import annotations

import time

from bev_mdo import sessions
from bev_mdo.launcher import Launcher, NodeProcess
from bev_mdo.ros_settings import participant_lease_s


class _Clock:
    def __init__(self):
        self.t = 1000.0

    def __call__(self):
        return self.t


def _launcher(recorder_died=None, restarted_at=()):
    la = Launcher({})
    la.nodes = [NodeProcess("recorder", [], restart=False, died=recorder_died),
                NodeProcess("vehicle_mass", [], restart_times=list(restarted_at))]
    return la


def test_the_wait_ends_at_once_when_the_recorder_is_dead():
    assert sessions.acks_needless(_launcher(recorder_died=-9))()


def test_the_wait_goes_on_while_every_node_lives(monkeypatch):
    clock = _Clock()
    monkeypatch.setattr(sessions.time, "monotonic", clock)
    needless = sessions.acks_needless(_launcher())
    for _ in range(5):
        assert not needless()
        clock.t += 10.0


def test_a_node_that_died_within_the_lease_ends_the_wait_after_the_grace(monkeypatch):
    clock = _Clock()
    monkeypatch.setattr(sessions.time, "monotonic", clock)
    needless = sessions.acks_needless(_launcher(restarted_at=[clock.t - 0.5]))  # (time.monotonic is patched)
    assert not needless()              # a live recorder gets its grace to acknowledge
    clock.t += sessions.ACK_GRACE_S
    assert needless()
    clock.t += participant_lease_s() + sessions.ACK_GRACE_S  # the dead reader's lease is long over: wait again
    assert not needless()


def test_died_within_sees_restarts_and_deaths_in_the_window():
    now = time.monotonic()
    assert _launcher(restarted_at=[now - 1.0]).died_within(3.0)
    assert not _launcher(restarted_at=[now - 10.0]).died_within(3.0)
    la = _launcher()
    la.nodes[0].died_at = now - 2.0
    assert la.died_within(3.0) and not la.died_within(1.0)
    assert not _launcher().died_within(3.0)
