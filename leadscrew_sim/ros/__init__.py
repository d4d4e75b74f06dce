"""The ROS 2 side: the node, its parameters, diagnostics and deadline timing."""
