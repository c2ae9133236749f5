"""ros_settings.participant_lease_s: the lease the end of a run allows a killed reader, read from the
Fast DDS profile in use (bev_mdo's own, or the user's) instead of repeating it."""
from __future__ import annotations

import xml.etree.ElementTree as ET

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
