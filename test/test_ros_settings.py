"""ros_settings.participant_lease_s: the lease the end of a run allows a killed reader, read from the
Fast DDS profile in use (bev_mdo's own, or the user's) instead of repeating it."""
from __future__ import annotations

import xml.etree.ElementTree as ET

import pytest

from bev_mdo.ros_settings import DDS_PROFILE, FASTDDS_DEFAULT_LEASE_S, participant_lease_s

NS = "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"


def _profile(tmp_path, lease: str = "") -> str:
    path = tmp_path / "mine.xml"
    path.write_text(f'<?xml version="1.0"?>\n<profiles xmlns="{NS}">\n'
                    '  <participant profile_name="other"><rtps><builtin><discovery_config><leaseDuration>'
                    '<sec>99</sec></leaseDuration></discovery_config></builtin></rtps></participant>\n'
                    '  <participant profile_name="mine" is_default_profile="true"><rtps><builtin><discovery_config>'
                    f'{lease}</discovery_config></builtin></rtps></participant>\n</profiles>\n')
    return str(path)


def test_bev_mdos_profile_gives_the_lease_written_in_it():
    lease = ET.parse(DDS_PROFILE).getroot().find(f".//{{{NS}}}leaseDuration")
    written = float(lease.findtext(f"{{{NS}}}sec")) + float(lease.findtext(f"{{{NS}}}nanosec", "0")) / 1e9
    assert participant_lease_s({}) == written
    assert written != FASTDDS_DEFAULT_LEASE_S  # bev_mdo's profile does set its own


def test_a_users_profile_is_read_its_default_participant_first(tmp_path):
    path = _profile(tmp_path, "<leaseDuration><sec>7</sec><nanosec>500000000</nanosec></leaseDuration>")
    assert participant_lease_s({"FASTRTPS_DEFAULT_PROFILES_FILE": path}) == 7.5
    assert participant_lease_s({"FASTDDS_DEFAULT_PROFILES_FILE": path,
                                "FASTRTPS_DEFAULT_PROFILES_FILE": str(DDS_PROFILE)}) == 7.5


def test_fast_dds_default_when_the_profile_sets_none_or_cannot_be_read(tmp_path):
    for env in ({"FASTRTPS_DEFAULT_PROFILES_FILE": _profile(tmp_path)},
                {"FASTRTPS_DEFAULT_PROFILES_FILE": _profile(tmp_path, "<leaseDuration><sec>DURATION_INFINITY</sec>"
                                                                     "</leaseDuration>")},
                {"FASTRTPS_DEFAULT_PROFILES_FILE": str(tmp_path / "absent.xml")}):
        assert participant_lease_s(env) == FASTDDS_DEFAULT_LEASE_S
    (tmp_path / "broken.xml").write_text("<profiles")
    assert participant_lease_s({"FASTRTPS_DEFAULT_PROFILES_FILE": str(tmp_path / "broken.xml")}) == FASTDDS_DEFAULT_LEASE_S


_ROS_KEYS = ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_STATIC_PEERS", "ROS_DISCOVERY_SERVER",
             "FASTRTPS_DEFAULT_PROFILES_FILE", "BEV_MDO_ROS_ENVIRONMENT")


@pytest.mark.parametrize("launched", [False, True])
def test_a_node_executable_started_by_hand_joins_the_discovery_its_config_states(tmp_path, monkeypatch, launched):
    # `ros2 run bev_mdo coordinator_node --ros-args -p config:=shared.yaml` ignored the config's ros: section
    # (docs/across-machines.md: "Discovery is set in the config's ros: section"): it never found nodes behind
    # a discovery server. A process bev-mdo starts keeps the environment the launcher gave it.
    import os

    from bev_mdo.ros.run import _config_ros_environment
    from bev_mdo.ros_settings import ros_environment, validate_ros

    for key in _ROS_KEYS:
        monkeypatch.delenv(key, raising=False)
    monkeypatch.setenv("ROS_DOMAIN_ID", "196")
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    if launched:
        monkeypatch.setenv("BEV_MDO_ROS_ENVIRONMENT", "1")
    assert ros_environment(validate_ros({}))["BEV_MDO_ROS_ENVIRONMENT"] == "1"  # what the launcher passes on
    server = tmp_path / "server.yaml"
    server.write_text('ros: {discovery: server, discovery_server: "10.231.7.1:11811", domain_id: 197}\n')
    _config_ros_environment(["--ros-args", "-p", f"config:={server}", "-p", "run_id:=x"])
    if launched:
        assert os.environ["ROS_DOMAIN_ID"] == "196" and "ROS_DISCOVERY_SERVER" not in os.environ
    else:
        assert os.environ["ROS_DISCOVERY_SERVER"] == "10.231.7.1:11811" and os.environ["ROS_DOMAIN_ID"] == "197"


def test_a_config_that_states_no_discovery_leaves_the_environments(tmp_path, monkeypatch):
    import os

    from bev_mdo.ros.run import _config_ros_environment

    for key in _ROS_KEYS:
        monkeypatch.delenv(key, raising=False)
    monkeypatch.setenv("ROS_DOMAIN_ID", "196")
    monkeypatch.setenv("ROS_STATIC_PEERS", "10.231.7.2")
    plain = tmp_path / "plain.yaml"
    plain.write_text("ros: {timeout_s: 5}\n")
    _config_ros_environment(["--ros-args", "-p", f"config:={plain}"])
    assert os.environ["ROS_STATIC_PEERS"] == "10.231.7.2" and os.environ["ROS_DOMAIN_ID"] == "196"
    only_domain = tmp_path / "domain.yaml"
    only_domain.write_text("ros: {domain_id: 198}\n")
    _config_ros_environment(["--ros-args", "-p", f"config:={only_domain}"])
    assert os.environ["ROS_STATIC_PEERS"] == "10.231.7.2" and os.environ["ROS_DOMAIN_ID"] == "198"
