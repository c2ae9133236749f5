"""The node executables of the package (``ros2 run bev_mdo <exe>``): a table, importing nothing."""
from __future__ import annotations

# executable -> built-in discipline name it serves (None: not a discipline node)
DISCIPLINE_EXES = {
    "vehicle_mass_node": "vehicle_mass",
    "energy_node": "energy",
    "range_node": "range",
    "acceleration_node": "acceleration",
    "motor_speed_node": "motor_speed",
    "cost_node": "cost",
}
OTHER_EXES = ("discipline_node", "coordinator_node", "recorder_node", "composed_node")
