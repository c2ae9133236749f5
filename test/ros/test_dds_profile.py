"""bev_mdo's Fast DDS profile (bev_mdo/data/fastdds_profile.xml): used unless the user names one,
parsed by Fast DDS without complaint, and shipped in the installed package."""
from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path



from bev_mdo.ros import DDS_PROFILE  # noqa: E402
from bev_mdo.testing import REPO, ros_env  # noqa: E402

PROFILE_VARS = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")

# A node with a reliable publisher and subscription: Fast DDS loads the default profile when
# the participant is created and applies it to the writer.
CHILD = textwrap.dedent(
    """
    import os
    import bev_mdo.ros
    import rclpy
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String
    rclpy.init()
    node = rclpy.create_node("profile_probe")
    qos = QoSProfile(depth=4, reliability=ReliabilityPolicy.RELIABLE)
    node.create_publisher(String, "/bev_mdo_test/profile", qos)
    node.create_subscription(String, "/bev_mdo_test/profile", lambda m: None, qos)
    print("PROFILE=" + os.environ.get("FASTRTPS_DEFAULT_PROFILES_FILE", ""))
    node.destroy_node()
    rclpy.shutdown()
    """
)


def _run(env: dict, cwd: Path | str = REPO) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", CHILD], env=env, cwd=cwd, capture_output=True, text=True,
                          timeout=60)


def _profile(out: subprocess.CompletedProcess) -> str:
    return next(line for line in out.stdout.splitlines() if line.startswith("PROFILE="))[len("PROFILE="):]


def _complaints(out: subprocess.CompletedProcess) -> str:
    """Fast DDS log lines (it logs to stdout: "[XMLPARSER Error] ...", "[XMLProfileManager Error] ...")."""
    return "\n".join(line for line in (out.stdout + out.stderr).splitlines() if "Error" in line or "XML" in line)


def _env(ros_domain: int) -> dict:
    env = ros_env(ros_domain)
    for k in PROFILE_VARS:
        env.pop(k, None)
    return env


def test_profile_is_used_and_fast_dds_parses_it(ros_domain):
    out = _run(_env(ros_domain))
    assert out.returncode == 0, out.stderr
    assert Path(_profile(out)) == DDS_PROFILE
    assert DDS_PROFILE.is_file()
    assert _complaints(out) == ""  # a profile Fast DDS cannot read is logged as "[XMLPARSER Error] ..."


def test_the_profile_with_a_domains_localhost_peers_is_parsed(ros_domain):
    """The profile every bev_mdo process of a run gets (bev_mdo's plus the initial peers of the
    domain's participant ids from 32, ros_settings.localhost_peers_profile): Fast DDS reads it."""
    from bev_mdo.ros_settings import ros_environment, validate_ros

    env = ros_environment(validate_ros({"domain_id": ros_domain}), base=_env(ros_domain))
    out = _run(env)
    assert out.returncode == 0, out.stderr
    assert _profile(out).endswith(f"localhost_peers_domain{ros_domain}.xml")
    assert _complaints(out) == ""


def test_a_profile_the_user_names_is_kept(ros_domain, tmp_path):
    mine = tmp_path / "mine.xml"
    mine.write_text('<?xml version="1.0" encoding="UTF-8"?>\n'
                    '<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">\n'
                    '  <data_writer profile_name="mine"><qos/></data_writer>\n'
                    '</profiles>\n')
    env = {**_env(ros_domain), "FASTRTPS_DEFAULT_PROFILES_FILE": str(mine)}
    out = _run(env)
    assert out.returncode == 0, out.stderr
    assert _profile(out) == str(mine)
    assert _complaints(out) == ""


def test_the_installed_package_ships_the_profile(ros_domain, tmp_path):
    env = _env(ros_domain)
    env.pop("PYTHONPATH", None)  # the installed bev_mdo, as `ros2 run` starts it
    probe = subprocess.run([sys.executable, "-c", "import bev_mdo.ros as r; print(r.DDS_PROFILE)"], env=env,
                           cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert probe.returncode == 0, f"bev_mdo is not installed in this interpreter (./scripts/setup.sh installs it): {probe.stderr[-500:]}"
    installed = Path(probe.stdout.strip())
    assert installed != DDS_PROFILE and "site-packages" in installed.parts  # not the source tree's file
    assert installed.is_file()
    out = _run(env, cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert Path(_profile(out)) == installed
    assert _complaints(out) == ""
