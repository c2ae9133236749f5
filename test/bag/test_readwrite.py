"""A written bag reads back the same values with rosbags, mcap-ros2-support and our reader."""
from __future__ import annotations

import pytest
import yaml

from .conftest import CONFIG_YAML, DESIGN, T0_NS


def _key(type_name: str, m) -> tuple:
    """Comparable decoded values of one message (works for rclpy, rosbags and mcap objects)."""
    if type_name.endswith("EvaluationRequest"):
        return (m.run_id, int(m.evaluation_id), int(m.iteration), m.discipline,
                list(m.inputs.names), [float(v) for v in m.inputs.values],
                int(m.header.stamp.sec), int(m.header.stamp.nanosec))
    if type_name.endswith("EvaluationResult"):
        return (m.run_id, int(m.evaluation_id), m.discipline, int(m.status),
                [bool(v) for v in m.point_ok], list(m.outputs.names),
                [float(v) for v in m.outputs.values], float(m.compute_time_s))
    return (m.run_id, int(m.iteration), m.formulation, m.optimizer, float(m.objective),
            list(m.design.names), [float(v) for v in m.design.values],
            [float(v) for v in m.constraints.values], float(m.max_violation), bool(m.feasible),
            list(m.discipline_names), [int(v) for v in m.discipline_evaluations])


def _expected(msgs, topics=None):
    return [(t, _key(ty, m)) for t, ty, m in msgs if topics is None or t in topics]


def test_rosbags_reads_bag_directory(synthetic_bag):
    from rosbags.highlevel import AnyReader

    bag_dir, msgs = synthetic_bag
    got = []
    with AnyReader([bag_dir]) as reader:
        assert reader.message_count == len(msgs)
        for conn, _t, raw in reader.messages():
            got.append((conn.topic, _key(conn.msgtype, reader.deserialize(raw, conn.msgtype))))
    assert got == _expected(msgs)


def test_rosbags_reads_bare_mcap(synthetic_bag):
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag2 import Reader

    bag_dir, msgs = synthetic_bag

    with AnyReader([bag_dir / "run1_0.mcap"]) as reader:
        got = [(c.topic, _key(c.msgtype, reader.deserialize(raw, c.msgtype)))
               for c, _t, raw in reader.messages()]
    assert got == _expected(msgs)
    with Reader(bag_dir / "run1_0.mcap") as reader:
        assert reader.message_count == len(msgs)
        conns = {c.topic: c for c in reader.connections}
        assert conns["/bev_mdo/iteration"].ext.offered_qos_profiles[0].depth == 1000


def test_mcap_ros2_reads_values_and_times(synthetic_bag):
    from mcap_ros2.reader import read_ros2_messages

    bag_dir, msgs = synthetic_bag
    got, times = [], []
    for m in read_ros2_messages(str(bag_dir / "run1_0.mcap")):
        got.append((m.channel.topic, _key(m.schema.name, m.ros_msg)))
        times.append((m.log_time_ns, m.publish_time_ns))
    assert got == _expected(msgs)
    assert times == [(T0_NS + j * 1000, T0_NS + j * 1000 - 7) for j in range(len(msgs))]


def test_mcap_layout_is_rosbag2(synthetic_bag):
    from mcap.reader import make_reader

    bag_dir, msgs = synthetic_bag
    with open(bag_dir / "run1_0.mcap", "rb") as f:
        reader = make_reader(f)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
        assert summary.statistics.message_count == len(msgs)
        assert summary.statistics.chunk_count > 1
        for schema in summary.schemas.values():
            assert schema.encoding == "ros2msg"
            assert schema.name.startswith("bev_mdo_msgs/msg/")
        for channel in summary.channels.values():
            assert channel.message_encoding == "cdr"
            assert channel.metadata["topic_type_hash"].startswith("RIHS01_")
            qos = yaml.safe_load(channel.metadata["offered_qos_profiles"])
            assert qos[0]["reliability"] == "reliable" and qos[0]["history"] == "keep_last"
        records = {m.name: m.metadata for m in reader.iter_metadata()}
        inner = yaml.safe_load(records["rosbag2"]["serialized_metadata"])
        assert inner["message_count"] == len(msgs)
        assert records["bev_mdo"]["config_yaml"] == CONFIG_YAML
        assert {a.name for a in reader.iter_attachments()} == {"config.yaml"}


def test_schema_text_has_sorted_dependencies():
    from bev_mdo.bag.schema import SEPARATOR, full_definition, type_hash

    text = full_definition("bev_mdo_msgs/msg/IterationRecord")
    parts = text.split("\n" + SEPARATOR + "\nMSG: ")
    names = [p.split("\n", 1)[0] for p in parts[1:]]
    # depth first, sorted at each level: NamedArray, then Header and Header's Time
    assert names == ["bev_mdo_msgs/NamedArray", "std_msgs/Header", "builtin_interfaces/Time"]
    assert parts[0].startswith("# Coordinator -> anyone")
    assert type_hash("bev_mdo_msgs/msg/IterationRecord").startswith("RIHS01_")


def test_metadata_yaml_counts(synthetic_bag):
    bag_dir, msgs = synthetic_bag
    info = yaml.safe_load((bag_dir / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["version"] == 9 and info["storage_identifier"] == "mcap"
    assert info["relative_file_paths"] == ["run1_0.mcap"]
    assert info["message_count"] == len(msgs)
    counts = {t["topic_metadata"]["name"]: t["message_count"] for t in info["topics_with_message_count"]}
    expected: dict[str, int] = {}
    for topic, _ty, _m in msgs:
        expected[topic] = expected.get(topic, 0) + 1
    assert counts == expected
    assert info["duration"]["nanoseconds"] == (len(msgs) - 1) * 1000
    assert info["starting_time"]["nanoseconds_since_epoch"] == T0_NS


def test_own_reader_config_and_counts(synthetic_bag):
    from bev_mdo import __version__
    from bev_mdo.bag.reader import open_bag, read_config

    bag_dir, msgs = synthetic_bag
    for path in (bag_dir, bag_dir / "run1_0.mcap"):
        bag = open_bag(path)
        assert not bag.truncated
        assert read_config(bag) == CONFIG_YAML
        assert bag.info["version"] == __version__ and bag.info["run_id"] == "run-1"
        got = [(m.topic, _key(m.type_name, obj)) for m, obj in bag.decoded()]
        assert got == _expected(msgs)
    only = [m.topic for m in open_bag(bag_dir).messages(["/bev_mdo/iteration"])]
    assert only == ["/bev_mdo/iteration"] * 20


def test_writer_refuses_existing_bag(synthetic_bag):
    from bev_mdo.bag.errors import BagError
    from bev_mdo.bag.writer import BagWriter

    with pytest.raises(BagError, match="already exists"):
        BagWriter(synthetic_bag[0])


def test_history_csv_and_last_iterate(synthetic_bag, tmp_path):
    import csv

    from bev_mdo.bag.history import history, last_iterate

    from .conftest import cli, design_of

    bag_dir, _ = synthetic_bag
    rows = history(bag_dir)
    assert [r["iteration"] for r in rows] == list(range(20))
    assert rows[7]["design"] == pytest.approx(design_of(7))
    assert rows[7]["constraints"] == {"range_km": 307.0}
    assert rows[3]["feasible"] is False and rows[5]["feasible"] is True
    assert rows[4]["discipline_evaluations"] == {"vehicle_mass": 5, "energy": 5}
    config, design, iteration = last_iterate(bag_dir)
    assert (config, iteration) == (CONFIG_YAML, 19) and design == pytest.approx(design_of(19))

    out = tmp_path / "h.csv"
    code, _, err = cli("history", str(bag_dir), "--csv", str(out))
    assert code == 0, err
    table = list(csv.DictReader(out.open()))
    assert len(table) == 20
    assert float(table[19]["design.motor_kw"]) == design_of(19)["motor_kw"]
    assert float(table[2]["objective"]) == 9980.0
    assert table[0]["evaluations.energy"] == "1"
    code, stdout, _ = cli("history", str(bag_dir))
    assert code == 0 and "SLSQP" in stdout and "20 records (iterations 0-19)" in stdout
    assert set(DESIGN) <= {k.split(".", 1)[1] for k in table[0] if k.startswith("design.")}


def test_history_and_last_iterate_parse_the_stored_config_once(synthetic_bag, monkeypatch):
    """history() parsed the stored config for the design names and again for the record window;
    last_iterate() a third time for the objective's sense. Once each now, with the same results."""
    from bev_mdo.bag.history import history, last_iterate

    bag_dir, _ = synthetic_bag
    expected_rows, expected_last = history(bag_dir), last_iterate(bag_dir)
    from bev_mdo import yamlload

    real, parsed = yamlload.load_yaml, []

    def counting(text, *args, **kwargs):
        parsed.append(text == CONFIG_YAML)
        return real(text, *args, **kwargs)

    monkeypatch.setattr(yamlload, "load_yaml", counting)
    assert history(bag_dir) == expected_rows
    assert parsed.count(True) == 1
    parsed.clear()
    assert last_iterate(bag_dir) == expected_last
    assert parsed.count(True) == 1


def test_bag_info_cli(synthetic_bag):
    from .conftest import cli

    code, out, _ = cli("bag", "info", str(synthetic_bag[0]))
    assert code == 0
    assert "/bev_mdo/result" in out and "40" in out and "messages:  100" in out


def test_report_writes_plots_and_markdown(synthetic_bag):
    from .conftest import cli

    bag_dir, _ = synthetic_bag
    code, out, err = cli("report", str(bag_dir))
    assert code == 0, err
    for name in ("convergence.png", "design.png", "discipline_time.png", "report.md"):
        path = bag_dir / name
        assert path.is_file() and str(path) in out
        if name.endswith(".png"):
            assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    md = (bag_dir / "report.md").read_text()
    assert "| vehicle_mass | 20 |" in md        # 20 results for that discipline
    assert "| 0.250 | 0.250 |" in md           # latency p50 | p95 from header stamps: 0.25 ms
    # this bag's config is a fragment no discipline can be built from: no declared unit, and none is
    # guessed from the name (motor_kw)
    assert "| motor_kw |  | 99 |" in md and "Best feasible objective 9810 at iteration 19" in md
    assert CONFIG_YAML.rstrip() in md


@pytest.mark.parametrize("name", ["{mcap}", "metadata.yaml"])
def test_history_does_not_write_its_csv_over_the_bag_it_read(synthetic_bag, name):
    """history BAG --csv BAG/BAG_0.mcap printed 'wrote 20 records' and the bag was lost (not an MCAP file)."""
    from bev_mdo.bag.reader import find_mcap

    from .conftest import cli

    bag_dir, _ = synthetic_bag
    target = bag_dir / name.format(mcap=find_mcap(bag_dir).name)
    before = target.read_bytes()
    code, _, err = cli("history", str(bag_dir), "--csv", str(target))
    assert code == 2 and f"that is the bag's own {target.name}; write the CSV elsewhere" in err
    assert target.read_bytes() == before
    assert cli("history", str(bag_dir), "--csv", str(bag_dir / "history.csv"))[0] == 0  # beside it, as report's files


def test_a_stored_config_is_parsed_within_the_yaml_limits():
    """A bag may come from anyone: its stored config was parsed with plain yaml.safe_load, so an alias bomb
    (a few lines, 10^9 values once expanded) reached every reader as a config. It is read as no config now,
    as any other unreadable one, and a resume says which bag and why."""
    from bev_mdo.bag.stored import StoredConfig

    bomb = "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"{c}: &{c} [{', '.join(['*' + p] * 10)}]\n" for p, c in zip("abcdefgh", "bcdefghi"))
    assert len(yaml.safe_load(bomb)["i"]) == 10  # plain YAML takes it (len: its repr would expand it)
    assert len(StoredConfig.parse(bomb).data) == 0
    assert StoredConfig.parse(CONFIG_YAML).data == yaml.safe_load(CONFIG_YAML)


def test_resume_names_the_bag_whose_config_cannot_be_read_back(synthetic_bag, monkeypatch):
    from bev_mdo import yamlload
    from bev_mdo.cli.resume import resume_point

    bag_dir, _ = synthetic_bag
    monkeypatch.setattr(yamlload, "MAX_YAML_BYTES", 16)  # as a cycle trace recorded whole past 8 MiB was
    with pytest.raises(ValueError, match=f"{bag_dir}: the bag's configuration cannot be read back .*YAML text"):
        resume_point(str(bag_dir))
