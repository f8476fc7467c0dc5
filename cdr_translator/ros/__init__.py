"""The ROS 2 edge: the only place that imports rclpy (both nodes, their parts, a client)."""
