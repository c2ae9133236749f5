"""Declared units over ROS: the discipline node of a consumer converts a metre coupling into its
kilometres on entry, as in process, on the data-flow path and wave by wave, partials included."""
from __future__ import annotations

import sys

import numpy as np
import pytest
import yaml

from bev_mdo.config import load_config, resolve_disciplines
from bev_mdo.mdo.evaluator import InProcessEvaluator
from bev_mdo.mdo.mda import MDA
from bev_mdo.ros import coordinator_node
from bev_mdo.launcher import Launcher
from bev_mdo.processes import discipline_argv
from bev_mdo.testing import REPO, ros_env

sys.path.insert(0, str(REPO / "test" / "mdo"))
from test_units import MODULE  # noqa: E402

NAMES = ["trip", "fuel"]
X = {"speed_kmh": np.array([50.0, 87.5, 120.0]), "time_h": np.array([1.0, 1.75, 0.5])}


@pytest.fixture(scope="module")
def config(tmp_path_factory):
    folder = tmp_path_factory.mktemp("units")
    (folder / "trip_ros.py").write_text("import numpy as np\n" + MODULE.format(dist="m", scale="1000.0"))
    raw = {"name": "units_ros", "search_path": [str(folder)],
           "disciplines": [{"name": n, "class": f"trip_ros:{n.title()}"} for n in NAMES],
           "problem": {"objective": "fuel_l", "constraints": {},
                       "design_variables": {k: {"lower": 0.1, "upper": 200, "initial": 1} for k in X}},
           "ros": {"timeout_s": 10.0, "retries": 1, "discovery_wait_s": 60.0}}
    path = folder / "units.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return str(path)


@pytest.fixture(scope="module")
def coordinator(ros_domain, rclpy_context, config, tmp_path_factory):
    launcher = Launcher(ros_env(ros_domain), log_dir=tmp_path_factory.mktemp("logs"))
    for n in NAMES:
        launcher.add(n, discipline_argv(n, config))
    node = coordinator_node.CoordinatorNode(load_config(config), context=rclpy_context, node_name="units_probe")
    try:
        node.evaluator.wait_for_disciplines(NAMES, 60.0)
        yield node.evaluator
    finally:
        node.evaluator.close()
        node.destroy_node()
        launcher.stop()


@pytest.mark.parametrize("data_flow", [True, False])
def test_a_metre_coupling_is_converted_by_the_consumer_node(coordinator, config, data_flow):
    res = MDA(coordinator, disciplines=NAMES, data_flow=data_flow).run(X)
    local = MDA(InProcessEvaluator(resolve_disciplines(load_config(config))), data_flow=data_flow).run(X)
    assert res.ok.all() and local.ok.all()
    km = X["speed_kmh"] * X["time_h"]
    np.testing.assert_allclose(res.values["dist"], 1000.0 * km, rtol=1e-15)  # the producer's metres
    np.testing.assert_allclose(res.values["fuel_l"], 0.06 * km + X["time_h"], rtol=1e-12)  # read in km
    np.testing.assert_array_equal(res.values["fuel_l"], local.values["fuel_l"])


def test_partials_over_ros_are_per_metre(coordinator):
    (res,) = coordinator.evaluate([("fuel", {"dist": np.array([2000.0]), "time_h": np.array([1.0])})], partials=True)
    assert res.ok.all()
    assert res.outputs["fuel_l"][0] == pytest.approx(0.06 * 2 + 1, rel=1e-14)
    assert res.extra["partials"][("fuel_l", "dist")][0] == pytest.approx(0.06e-3, rel=1e-14)
