"""The MDO engine: disciplines, coupling graph, MDA, formulations, optimisers. No ROS import here."""
