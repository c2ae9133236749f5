"""`bev-mdo sweep --attach` and `compare --attach`: the grid as ONE batch through the running
discipline nodes gives what the in-process sweep gives."""
from __future__ import annotations

import csv

import pytest


from bev_mdo.cli import main  # noqa: E402

ROS_DOMAIN = 57


def _rows(path):
    return list(csv.DictReader(open(path)))


def test_sweep_over_ros_equals_in_process(leaf_nodes, leaf_config, tmp_path):
    vary = ["--vary", "motor_kw=40:120:5", "gear_ratio=6:10:3"]
    assert main(["sweep", str(leaf_config), *vary, "--out", str(tmp_path / "ros"), "--attach", "--no-plots"]) == 0
    assert main(["sweep", str(leaf_config), *vary, "--out", str(tmp_path / "local"), "--no-plots",
                 "--transport", "inprocess"]) == 0
    ros, local = _rows(tmp_path / "ros/sweep.csv"), _rows(tmp_path / "local/sweep.csv")
    assert len(ros) == len(local) == 15
    for a, b in zip(ros, local):
        assert a == b


def test_compare_over_ros(leaf_nodes, leaf_config, capsys):
    rc = main(["compare", str(leaf_config), "--attach", "--json",
               "--design", "motor_kw=80,gear_ratio=7.94,battery_kwh=24", "--design", "motor_kw=90"])
    assert rc == 0
    import json

    d = json.loads(capsys.readouterr().out)["designs"]
    assert d[0]["vehicle_mass_kg"] == pytest.approx(1590.0) and d[1]["motor_kw"] == 90


def test_doe_over_ros_equals_in_process_records_its_bag_and_says_its_domain(leaf_nodes, leaf_config, ros_domain, tmp_path,
                                                                           capsys):
    doe = ["--doe", "sobol", "--samples", "16", "--seed", "4", "--no-plots"]
    assert main(["sweep", str(leaf_config), *doe, "--out", str(tmp_path / "ros"), "--attach"]) == 0
    assert f"on ROS domain {ros_domain} " in capsys.readouterr().err
    assert main(["sweep", str(leaf_config), *doe, "--out", str(tmp_path / "local"), "--transport", "inprocess"]) == 0
    ros, local = _rows(tmp_path / "ros/sweep.csv"), _rows(tmp_path / "local/sweep.csv")
    assert len(ros) == 16 and ros == local
    from bev_mdo.bag.reader import open_bag

    bag = open_bag(tmp_path / "ros" / "bag")
    assert bag.message_count == 16


def test_check_totals_over_ros_equals_in_process(leaf_nodes, leaf_config, capsys):
    import json

    reports = []
    for transport in (["--attach"], ["--transport", "inprocess"]):
        code = main(["check-totals", str(leaf_config), *transport, "--json"])
        reports.append(json.loads(capsys.readouterr().out))
        assert code == 0, reports[-1]
    ros, local = reports
    assert [(r["of"], r["wrt"]) for r in ros["rows"]] == [(r["of"], r["wrt"]) for r in local["rows"]]
    for a, b in zip(ros["rows"], local["rows"]):
        assert a["total"] == pytest.approx(b["total"], rel=1e-9, abs=1e-12), a
