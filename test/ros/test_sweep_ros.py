"""`bev-mdo sweep --transport ros` and `compare --transport ros`: the grid as ONE batch through the
running discipline nodes gives what the in-process sweep gives."""
from __future__ import annotations

import csv

import pytest
import yaml


from bev_mdo.cli import main  # noqa: E402
from bev_mdo.ros.launch import Launcher, discipline_argv  # noqa: E402
from bev_mdo.testing import REPO, ros_env  # noqa: E402

ROS_DOMAIN = 57
BUILTINS = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost"]


@pytest.fixture(scope="module")
def config(ros_domain, tmp_path_factory):
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["ros"] = {"domain_id": ros_domain, "discovery_wait_s": 60.0}
    path = tmp_path_factory.mktemp("cfg") / "leaf.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def nodes(ros_domain, config, tmp_path_factory):
    launcher = Launcher(ros_env(ros_domain), log_dir=tmp_path_factory.mktemp("logs"))
    for name in BUILTINS:
        launcher.add(name, discipline_argv(name, str(config)))
    yield launcher
    launcher.stop()


def _rows(path):
    return list(csv.DictReader(open(path)))


def test_sweep_over_ros_equals_in_process(nodes, config, tmp_path):
    vary = ["--vary", "motor_kw=40:120:5", "gear_ratio=6:10:3"]
    assert main(["sweep", str(config), *vary, "--out", str(tmp_path / "ros"), "--transport", "ros", "--no-plots"]) == 0
    assert main(["sweep", str(config), *vary, "--out", str(tmp_path / "local"), "--no-plots"]) == 0
    ros, local = _rows(tmp_path / "ros/sweep.csv"), _rows(tmp_path / "local/sweep.csv")
    assert len(ros) == len(local) == 15
    for a, b in zip(ros, local):
        assert a == b


def test_compare_over_ros(nodes, config, capsys):
    rc = main(["compare", str(config), "--transport", "ros", "--json",
               "--design", "motor_kw=80,gear_ratio=7.94,battery_kwh=24", "--design", "motor_kw=90"])
    assert rc == 0
    import json

    d = json.loads(capsys.readouterr().out)["designs"]
    assert d[0]["vehicle_mass_kg"] == pytest.approx(1590.0) and d[1]["motor_kw"] == 90


def test_doe_over_ros_equals_in_process_records_its_bag_and_says_its_domain(nodes, config, ros_domain, tmp_path,
                                                                           capsys):
    doe = ["--doe", "sobol", "--samples", "16", "--seed", "4", "--no-plots"]
    assert main(["sweep", str(config), *doe, "--out", str(tmp_path / "ros"), "--transport", "ros"]) == 0
    assert f"on ROS domain {ros_domain} " in capsys.readouterr().err
    assert main(["sweep", str(config), *doe, "--out", str(tmp_path / "local")]) == 0
    ros, local = _rows(tmp_path / "ros/sweep.csv"), _rows(tmp_path / "local/sweep.csv")
    assert len(ros) == 16 and ros == local
    from bev_mdo.bag.reader import open_bag

    bag = open_bag(tmp_path / "ros" / "bag")
    assert bag.message_count == 16


def test_check_totals_over_ros_equals_in_process(nodes, config, capsys):
    import json

    reports = []
    for transport in ("ros", "inprocess"):
        code = main(["check-totals", str(config), "--transport", transport, "--json"])
        reports.append(json.loads(capsys.readouterr().out))
        assert code == 0, reports[-1]
    ros, local = reports
    assert [(r["of"], r["wrt"]) for r in ros["rows"]] == [(r["of"], r["wrt"]) for r in local["rows"]]
    for a, b in zip(ros["rows"], local["rows"]):
        assert a["total"] == pytest.approx(b["total"], rel=1e-9, abs=1e-12), a
