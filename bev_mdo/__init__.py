"""bev_mdo: distributed MDO of battery-electric-vehicle powertrains over ROS 2."""

__version__ = "0.1.0"
