"""A run whose own recorder exits during start-up stops at once and says why. It waited for the recorder's
declaration until the start-up timeout (60 s without progress), then said only that the recorder "did not
declare itself"; the recorder's own error line (e.g. `recorder_node: error: same/x: bag already exists`)
was in its log alone."""
from __future__ import annotations

import sys

from bev_mdo.cli import main

ROS_DOMAIN = 215
WHY = "recorder_node: error: the test's recorder refuses to start"


def test_a_recorder_that_exits_during_start_up_stops_the_run_with_its_error_line(ros_domain, leaf_config, tmp_path,
                                                                                 monkeypatch, capsys):
    from bev_mdo import launcher

    def failing_recorder(run_launcher, bag, resolved, run_id):
        run_launcher.add("recorder", [sys.executable, "-c", f"import sys; print({WHY!r}, file=sys.stderr); sys.exit(2)"],
                         restart=False)
        return 1

    monkeypatch.setattr(launcher, "start_recorder", failing_recorder)
    bag = tmp_path / "bag"
    status = main(["optimize", str(leaf_config), "--bag", str(bag), "--quiet"])
    err = capsys.readouterr().err
    assert status == 6, err
    last = err.strip().splitlines()[-1]
    assert f"the run's recorder exited with 2 during start-up: {WHY} (its log: {bag / 'logs' / 'recorder.log'})" in last, err
