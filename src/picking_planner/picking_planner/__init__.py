"""The planner node (``picking-planner``) and the coordinator of several arms (``picking-harvester``): ROS
shells around :mod:`picking_core`."""
