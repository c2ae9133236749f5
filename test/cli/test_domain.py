"""The ROS domain rule: flag > the config's ros.domain_id > ROS_DOMAIN_ID > 77,
with one line when the config overrides the environment; every command that talks ROS has --domain-id."""
from __future__ import annotations

import argparse

import pytest

from bev_mdo.cli import build_parser
from bev_mdo.api.transport import ros_section
from bev_mdo.ros_settings import choose_domain


@pytest.mark.parametrize("section,flag,env,want,noted", [
    ({}, None, {}, 77, False),
    ({}, None, {"ROS_DOMAIN_ID": "42"}, 42, False),
    ({"domain_id": 42}, None, {"ROS_DOMAIN_ID": "42"}, 42, False),
    ({"domain_id": 77}, None, {"ROS_DOMAIN_ID": "42"}, 77, True),
    ({"domain_id": 77}, 5, {"ROS_DOMAIN_ID": "42"}, 5, False),
    ({}, 5, {"ROS_DOMAIN_ID": "42"}, 5, False),
    ({}, None, {"ROS_DOMAIN_ID": "not a number"}, 77, False),
])
def test_choose_domain(section, flag, env, want, noted):
    got, note = choose_domain(section, flag, env)
    assert got == want and (note is not None) == noted
    if noted:
        assert note == "ros.domain_id 77 of the config overrides ROS_DOMAIN_ID=42 of the environment"


def test_ros_section_says_it_once_on_stderr(monkeypatch, capsys):
    monkeypatch.setenv("ROS_DOMAIN_ID", "42")
    args = argparse.Namespace(domain_id=None)
    for _ in range(2):
        assert ros_section({"ros": {"domain_id": 77}}, args)["domain_id"] == 77
    assert capsys.readouterr().err.splitlines() == [
        "bev-mdo: ros.domain_id 77 of the config overrides ROS_DOMAIN_ID=42 of the environment"]
    assert ros_section({"ros": {}}, argparse.Namespace(domain_id=None))["domain_id"] == 42


@pytest.mark.parametrize("command", [["optimize", "c.yaml"], ["evaluate", "c.yaml"], ["sensitivity", "c.yaml"],
                                     ["node", "energy"], ["resume", "bag"], ["pareto", "c.yaml"], ["record"],
                                     ["replay", "bag"]])
def test_every_command_that_talks_ros_takes_domain_id(command):
    args = build_parser().parse_args([*command, "--domain-id", "23"])
    assert args.domain_id == 23



def test_localhost_discovery_reaches_participant_ids_past_31(monkeypatch, tmp_path):
    """rmw_fastrtps's LOCALHOST range announces to the ports of participant ids 0-31 only; the profile
    every bev_mdo process gets is bev_mdo's own plus 127.0.0.1 at the discovery port of each id from 32
    (RTPS 9.6.1.1)."""
    import xml.etree.ElementTree as ET

    from bev_mdo import ros_settings
    from bev_mdo.ros_settings import DDS_PROFILE, ros_environment, validate_ros

    monkeypatch.setattr(ros_settings, "_PROFILE_DIR", tmp_path / "profiles")
    ns = "{http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles}"
    env = ros_environment(validate_ros({"domain_id": 219}), base={})
    root = ET.parse(env["FASTRTPS_DEFAULT_PROFILES_FILE"]).getroot()
    peers = [(u.find(f"{ns}address").text, int(u.find(f"{ns}port").text))
             for u in root.find(f"{ns}participant/{ns}rtps/{ns}builtin/{ns}initialPeersList").iter(f"{ns}udpv4")]
    assert peers == [("127.0.0.1", 7400 + 250 * 219 + 10 + 2 * i) for i in range(32, 120)]
    # the rest is bev_mdo's profile, unchanged
    peers_list = root.find(f"{ns}participant/{ns}rtps/{ns}builtin/{ns}initialPeersList")
    root.find(f"{ns}participant/{ns}rtps/{ns}builtin").remove(peers_list)
    assert ET.tostring(root) == ET.tostring(ET.parse(DDS_PROFILE).getroot())
    # the last domain: only the ids whose port exists (32-62); ours for another domain is replaced
    env232 = ros_environment(validate_ros({"domain_id": 232}), base=env)
    ports = [int(p.text) for p in ET.parse(env232["FASTRTPS_DEFAULT_PROFILES_FILE"]).getroot().iter(f"{ns}port")]
    assert ports[-1] == 65534 and len(ports) == 31
    # a profile the user names wins; subnet discovery gets bev_mdo's profile without peers
    for var in ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE"):
        assert ros_environment(validate_ros({}), base={var: "/my.xml"}).get("FASTRTPS_DEFAULT_PROFILES_FILE") == (
            "/my.xml" if var.startswith("FASTRTPS") else None)
    assert ros_environment(validate_ros({"discovery": "subnet"}), base=env)["FASTRTPS_DEFAULT_PROFILES_FILE"] == str(
        DDS_PROFILE)
