"""A per-run key left by a run that never wrote its bag does not block a re-run with the same --bag."""
from __future__ import annotations

import os

from bev_mdo.protocol.signing import with_run_key
from bev_mdo.sessions import key_dir_for


def test_a_stale_key_of_a_bag_never_written_is_replaced(tmp_path):
    bag = tmp_path / "bags" / "run1"
    first = with_run_key({"ros": {}}, key_dir_for(bag))["ros"]["sign_key_file"]  # the run then failed: no bag
    old = open(first).read()
    again = with_run_key({"ros": {}}, key_dir_for(bag))["ros"]["sign_key_file"]  # raised FileExistsError before
    assert again == first and open(again).read() != old  # same place, a fresh key


def test_the_key_of_an_existing_bag_is_left_alone(tmp_path):
    bag = tmp_path / "bags" / "run1"
    key = with_run_key({"ros": {}}, key_dir_for(bag))["ros"]["sign_key_file"]
    bag.mkdir(parents=True)
    (bag / "run1_0.mcap").write_bytes(b"")  # the recorder opened its file: the bag exists
    key_dir_for(bag)
    assert open(key).read()  # still there: that bag's run (and `resume`'s check) own it


def test_a_key_of_a_start_up_stopped_before_the_recorder_is_replaced(tmp_path):
    """Ctrl-C during start-up leaves the bag directory with the nodes' logs only; re-running with the
    same --bag raised FileExistsError on the key (exit 7)."""
    bag = tmp_path / "bags" / "run1"
    first = with_run_key({"ros": {}}, key_dir_for(bag))["ros"]["sign_key_file"]
    (bag / "logs").mkdir(parents=True)
    old = open(first).read()
    again = with_run_key({"ros": {}}, key_dir_for(bag))["ros"]["sign_key_file"]
    assert again == first and open(again).read() != old


def test_a_per_run_key_is_readable_by_its_owner_only(tmp_path):
    key = with_run_key({"ros": {}}, key_dir_for(tmp_path / "bags" / "run1"))["ros"]["sign_key_file"]
    assert open(key).read() and os.stat(key).st_mode & 0o077 == 0
