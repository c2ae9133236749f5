"""bev_mdo: an ament_python package, installable with colcon or with plain pip.

With pip, console scripts land in bin/, so the node executables are also shipped as
small wrappers into <prefix>/lib/bev_mdo/ through data_files: that is where
`ros2 run bev_mdo <exe>` looks (ament_index: share/ament_index/resource_index/packages/bev_mdo).
"""
import glob
import os
import shutil

from setuptools import find_packages, setup
from setuptools.command.build_py import build_py

MSG_DIR = os.path.join("msg_defs", "msg")


class BuildPyWithMessages(build_py):
    """Ship the .msg files inside the package (bev_mdo/protocol/msg/): bev_mdo.protocol generates
    its message types from them at import, with or without the source tree or a ROS build."""

    def run(self):
        super().run()
        target = os.path.join(self.build_lib, "bev_mdo", "protocol", "msg")
        os.makedirs(target, exist_ok=True)
        for path in sorted(glob.glob(os.path.join(MSG_DIR, "*.msg"))):
            shutil.copy(path, target)


PACKAGE = "bev_mdo"
NODES = [
    "vehicle_mass_node", "energy_node", "range_node", "acceleration_node",
    "motor_speed_node", "cost_node", "discipline_node", "coordinator_node", "recorder_node", "composed_node",
]

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(include=["bev_mdo", "bev_mdo.*"]),
    package_data={"bev_mdo": ["data/drive_cycles/*", "data/epa_2022_bev/*", "data/parameter_sets/*", "data/*.csv", "data/*.yaml", "data/*.xml", "config/*.yaml"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + PACKAGE]),
        ("share/" + PACKAGE, ["package.xml"]),
        ("share/" + PACKAGE + "/config", sorted(glob.glob("config/*.yaml"))),
        ("lib/" + PACKAGE, ["ros_lib/" + n for n in NODES]),
    ],
    install_requires=["setuptools", "numpy", "scipy", "pyyaml", "pint"],
    cmdclass={"build_py": BuildPyWithMessages},
    zip_safe=False,
    maintainer="bev_mdo developers",
    maintainer_email="bev-mdo@example.org",
    description="Distributed MDO of BEV powertrains over ROS 2",
    license="Apache-2.0",
    entry_points={
        "console_scripts": ["bev-mdo = bev_mdo.cli:main"]
        + [f"{n} = bev_mdo.ros.run:{n}" for n in NODES],
    },
)
