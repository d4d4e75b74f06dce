"""The ROS 2 side: the node, its command intake, parameters, diagnostics and deadline timing."""
