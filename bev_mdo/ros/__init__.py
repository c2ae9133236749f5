"""The ROS 2 layer: nodes, the ROS transport, recorder and replay (it only moves data).

Importing it points Fast DDS at bev_mdo's profile (``bev_mdo/data/fastdds_profile.xml``:
reliable writers without a heartbeat piggybacked on every sample) unless the process
environment already names a profile file; set ``FASTRTPS_DEFAULT_PROFILES_FILE`` to your own
file to replace it. Child processes inherit the setting.
"""
import os

from bev_mdo.ros_settings import DDS_PROFILE
_PROFILE_VARS = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")

if not any(v in os.environ for v in _PROFILE_VARS) and DDS_PROFILE.is_file():
    os.environ["FASTRTPS_DEFAULT_PROFILES_FILE"] = str(DDS_PROFILE)
