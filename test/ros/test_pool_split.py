"""Worker pools without ROS: the split of a batch among instances, throughput, suspects; launch plans."""
from __future__ import annotations

import pytest

from bev_mdo import binding
from bev_mdo.mdo.pool import Pool, split_rows, validate_mode


def _cover(parts, n):
    rows = [r for _, a, b in parts for r in range(a, b)]
    return rows == list(range(n))


@pytest.mark.parametrize("n", [0, 1, 2, 3, 7, 64, 1000, 1023])
@pytest.mark.parametrize("weights", [[1.0], [1.0, 1.0], [1.0, 3.0], [5.0, 1.0, 1.0, 0.01], [1.0] * 8])
def test_split_covers_every_row_once_in_order(n, weights):
    names = [f"i{k}" for k in range(len(weights))]
    parts = split_rows(n, names, weights)
    assert _cover(parts, n)
    if n >= len(weights):  # everyone gets at least one row, so everyone stays measured
        assert [p[0] for p in parts] == names


def test_split_is_proportional_to_throughput():
    parts = split_rows(1000, ["a", "b"], [100.0, 300.0])
    assert [(b - a) for _, a, b in parts] == [250, 750]


def test_pool_weights_from_measured_throughput_and_suspects():
    pool = Pool("energy")
    for i in ("a", "b", "c"):
        pool.revive(i)
    assert [b - a for _, a, b in pool.split(90, ["a", "b", "c"])] == [30, 30, 30]  # nothing measured: equal
    pool.record("a", 100, 1.0)   # 100 points/s
    pool.record("b", 100, 0.5)   # 200 points/s; c unmeasured counts as the mean, 150
    assert [b - a for _, a, b in pool.split(900, ["a", "b", "c"])] == [200, 400, 300]
    pool.fail("b", 40)
    assert "b" in pool.suspect and pool.stats["b"].failures == 1 and pool.stats["b"].reassigned_points == 40
    pool.revive("b")  # it declared itself again
    assert "b" not in pool.suspect
    assert pool.stats["a"].to_dict()["throughput_points_per_s"] == 100.0


def test_mode_is_validated():
    assert validate_mode("redundant") == "redundant"
    with pytest.raises(ValueError, match="ros.pool"):
        validate_mode("shared")


def test_target_tag_round_trip():
    tag = binding.target_tag("energy", "0123456789abcdef", "/energy_node_1")
    entry = binding.parse_tag(tag)["energy"]
    assert binding.split_target(entry) == ("0123456789abcdef", "energy_node_1")
    assert binding.split_target("0123456789abcdef") == ("0123456789abcdef", "")


def test_launch_plan_instances_and_compose():
    from bev_mdo.processes import parse_compose, parse_instances, plan_processes

    names = ["vehicle_mass", "energy", "range", "cost"]
    assert parse_instances("energy=3", names) == {"vehicle_mass": 1, "energy": 3, "range": 1, "cost": 1}
    assert set(parse_instances("2", names).values()) == {2}
    for bad in ("motor=2", "energy=x", "energy=0"):
        with pytest.raises(ValueError, match="--instances"):
            parse_instances(bad, names)
    assert parse_compose("all", names) == [names]
    assert parse_compose("none", names) == [[n] for n in names]
    assert parse_compose("vehicle_mass+range", names) == [["vehicle_mass", "range"], ["energy"], ["cost"]]
    with pytest.raises(ValueError, match="two groups"):
        parse_compose("range+cost,cost", names)
    plan = plan_processes(names, "/tmp/c.yaml", run_id="r", instance="ab",
                          instances={"energy": 2}, compose="all")
    labels = [label for label, _ in plan]
    assert labels == ["vehicle_mass+range+cost", "energy#0", "energy#1"]
    composed = plan[0][1]
    assert "composed_node" in composed and "disciplines:=vehicle_mass,range,cost" in composed
    assert "instance:='energy_node_ab_1'" in plan[2][1] and "run_id:='r'" in plan[2][1]


def test_launch_plan_compose_coordinator_and_node_names():
    """``--compose coordinator``: no process for the disciplines (they run in the coordinator's), a pool's
    instances keep one each; node_names_of names the nodes any planned process runs."""
    from bev_mdo.processes import beside_coordinator, node_names_of, parse_compose, plan_processes

    names = ["vehicle_mass", "energy", "range", "cost"]
    assert parse_compose("coordinator", names) == []
    assert beside_coordinator("coordinator", names) == names
    assert beside_coordinator("coordinator", names, {"energy": 2, "range": 1}) == ["vehicle_mass", "range", "cost"]
    assert beside_coordinator("all", names) == [] and beside_coordinator(None, names) == []
    plan = plan_processes(names, "/tmp/c.yaml", instances={"energy": 2}, compose="coordinator")
    assert [label for label, _ in plan] == ["energy#0", "energy#1"]
    assert [node_names_of(argv) for _, argv in plan] == [["energy_node_0"], ["energy_node_1"]]
    plan = plan_processes(names, "/tmp/c.yaml", instance="ab", compose="vehicle_mass+range")
    assert [node_names_of(argv) for _, argv in plan] == [["vehicle_mass_node_ab", "range_node_ab"],
                                                          ["energy_node_ab"], ["cost_node_ab"]]


def test_min_rows_keeps_every_share_at_least_that_large():
    pool = Pool("x")
    pool.stat("a").throughput, pool.stat("b").throughput, pool.stat("c").throughput = 10.0, 1.0, 1.0
    for n in range(0, 40):
        shares = pool.split(n, ["a", "b", "c"], min_rows=2)
        assert [r for _, a, b in shares for r in range(a, b)] == list(range(n))  # in order, each row once
        if n >= 2:
            assert all(b - a >= 2 for _, a, b in shares), (n, shares)
        assert len(shares) == max(1, min(3, n // 2))
    assert pool.split(3, ["a", "b", "c"], min_rows=2) == [("a", 0, 3)]  # the fastest instance takes it


def test_pool_min_rows_setting_and_the_split_it_gives():
    """``ros.pool_min_rows``: a population of 100 stays whole (one share, the fastest instance) when
    shares must hold 128 rows; 512 rows are still cut in two; per discipline or for every pool."""
    from bev_mdo.mdo.pool import min_rows_of
    from bev_mdo.ros_settings import validate_min_rows, validate_ros

    assert validate_ros({})["pool_min_rows"] == 1
    assert validate_ros({"pool_min_rows": {"energy": 128}})["pool_min_rows"] == {"energy": 128}
    for bad in (0, -3, 2.5, "128", True, {"energy": 0}):
        with pytest.raises(ValueError, match="ros.pool_min_rows"):
            validate_min_rows(bad)
    assert min_rows_of({"energy": 128}, "energy") == 128 and min_rows_of({"energy": 128}, "range") == 1
    assert min_rows_of(64, "range") == 64
    pool = Pool("energy")
    pool.stat("e0").throughput, pool.stat("e1").throughput = 70.0, 100.0
    assert pool.split(100, ["e0", "e1"], min_rows=128) == [("e1", 0, 100)]
    assert [(i, b - a) for i, a, b in pool.split(512, ["e0", "e1"], min_rows=128)] == [("e0", 211), ("e1", 301)]
    assert len(pool.split(100, ["e0", "e1"], min_rows=1)) == 2  # the default: every instance gets a share


def test_the_apis_instances_may_be_a_mapping_or_an_int():
    """Study.optimize(instances={"energy": 2}) was refused: "'{'energy': 2}' is not a whole number"."""
    from bev_mdo.processes import parse_instances

    names = ["vehicle_mass", "energy", "range", "cost"]
    assert parse_instances({"energy": 2}, names) == parse_instances("energy=2", names)
    assert parse_instances(3, names) == dict.fromkeys(names, 3)
    with pytest.raises(ValueError, match="no discipline 'enrgy'"):
        parse_instances({"enrgy": 2}, names)
    with pytest.raises(ValueError, match="'2.5' is not a whole number"):
        parse_instances({"energy": 2.5}, names)


def test_a_discipline_given_twice_or_an_empty_spec_is_refused():
    """``--instances energy=2,energy=3`` used to keep the last, ``--compose ""`` to run as none."""
    from bev_mdo.processes import parse_compose, parse_instances

    names = ["vehicle_mass", "energy", "range", "cost"]
    for bad, why in (("energy=2,energy=3", "energy: given twice"), ("", "give N"), ("2,energy=3", "not both")):
        with pytest.raises(ValueError, match=why):
            parse_instances(bad, names)
    for bad in ("", "  "):
        with pytest.raises(ValueError, match="--compose '': give coordinator, none, all or groups"):
            parse_compose(bad, names)
    assert parse_instances(None, names) == dict.fromkeys(names, 1)
