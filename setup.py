"""bev_mdo: an ament_python package, installable with colcon or with plain pip.

With pip, console scripts land in bin/, so the node executables are also shipped as
small wrappers into <prefix>/lib/bev_mdo/ through data_files: that is where
`ros2 run bev_mdo <exe>` looks (ament_index: share/ament_index/resource_index/packages/bev_mdo).
"""
import glob

from setuptools import find_packages, setup

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
    zip_safe=True,
    maintainer="bev_mdo developers",
    maintainer_email="bev-mdo@example.org",
    description="Distributed MDO of BEV powertrains over ROS 2",
    license="Apache-2.0",
    entry_points={
        "console_scripts": ["bev-mdo = bev_mdo.cli:main"]
        + [f"{n} = bev_mdo.ros.run:{n}" for n in NODES],
    },
)
