"""Per-point errors over ROS: a failing point among several is named by its index in the batch, as
in process, on the data-flow path (one request, results passed node to node), in waves (hub and
spoke) and in a loop on fewer rows than the batch. The errors travel as fields of the result
message (error_points/_reasons/_inputs), never read back from its text."""
from __future__ import annotations

import numpy as np
import pytest
import yaml

from bev_mdo.config import load_config
from bev_mdo.mdo.evaluator import InProcessEvaluator
from bev_mdo.mdo.mda import MDA
from bev_mdo.ros import coordinator_node
from bev_mdo.launcher import Launcher
from bev_mdo.processes import discipline_argv
from bev_mdo.testing import REPO, ros_env

TOYS = REPO / "test" / "mdo"
if str(TOYS) not in __import__("sys").path:
    __import__("sys").path.insert(0, str(TOYS))
from flow_toys import LOOP_X, chain, loop  # noqa: E402

# square fails at points 1 and 4, plus (on the rows 0, 2, 3) at point 2: each is named on its own
X = {"x": np.array([1.0, -1.0, 2.0, 3.0, -4.0]), "z": np.array([0.0, 0.0, 9.0, 1.0, 2.0])}


@pytest.fixture(scope="module")
def config(tmp_path_factory):
    """Both toy graphs in one config (the nodes and the coordinator bind the same one)."""
    raw = {"name": "point_errors", "search_path": [str(TOYS)],
           "disciplines": [{"name": d.name, "class": f"flow_toys:{type(d).__name__}"} for d in chain() + loop()],
           "problem": {"objective": "v", "constraints": {},
                       "design_variables": {k: {"lower": -10, "upper": 10, "initial": 1} for k in X}},
           "ros": {"timeout_s": 10.0, "retries": 1, "discovery_wait_s": 60.0}}
    path = tmp_path_factory.mktemp("cfg") / "toys.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return str(path)


@pytest.fixture(scope="module")
def nodes(ros_domain, config, tmp_path_factory):
    launcher = Launcher(ros_env(ros_domain), log_dir=tmp_path_factory.mktemp("logs"))
    for disc in chain() + loop():
        launcher.add(disc.name, discipline_argv(disc.name, config))
    yield launcher
    launcher.stop()
    for n in launcher.nodes:
        assert n.restarts == 0, f"{n.label} died: {n.log_path.read_text()[-2000:] if n.log_path else ''}"


@pytest.fixture(scope="module")
def coordinator(rclpy_context, nodes, config):
    node = coordinator_node.CoordinatorNode(load_config(config), context=rclpy_context,
                                            node_name="point_errors_probe")
    node.evaluator.wait_for_disciplines([d.name for d in chain() + loop()], 60.0)
    yield node.evaluator
    node.evaluator.close()
    node.destroy_node()


@pytest.mark.parametrize("data_flow", [True, False])
def test_a_failing_point_of_a_feed_forward_mda_is_named_by_its_index(coordinator, data_flow):
    flows = coordinator.flows
    res = MDA(coordinator, disciplines=[d.name for d in chain()], data_flow=data_flow).run(X)
    assert coordinator.flows == flows + int(data_flow)  # one data-flow request, or none (waves)
    local = MDA(InProcessEvaluator(chain()), data_flow=data_flow).run(X)
    assert res.ok.tolist() == local.ok.tolist() == [True, False, False, True, False]
    assert res.errors == local.errors
    assert res.messages[1] == "square: ValueError: x must be >= 0 at point 1 (x=-1)"
    assert res.messages[4] == "square: ValueError: x must be >= 0 at point 4 (x=-4)"
    assert res.messages[2] == "plus: non-finite output ['w'] at point 2 (y=4, z=9)"  # plus ran 4 rows


@pytest.mark.parametrize("method", ["gauss_seidel", "newton"])
def test_a_failing_point_of_a_loop_on_fewer_rows_is_named_by_its_batch_index(coordinator, method):
    res = MDA(coordinator, disciplines=[d.name for d in loop()], method=method).run(LOOP_X)
    local = MDA(InProcessEvaluator(loop()), method=method).run(LOOP_X)
    assert res.ok.tolist() == local.ok.tolist() == [False, True, False, False]
    assert res.errors == local.errors
    assert res.messages[2] == "loop_a: ValueError: a must be <= 5 at point 2 (a=7, y2=1)", res.messages[2]
    assert res.messages[3] == "loop_a: ValueError: a must be <= 5 at point 3 (a=8, y2=1)", res.messages[3]
    np.testing.assert_allclose(res.values["y1"][1], local.values["y1"][1], rtol=1e-12)
