"""ROS-free core of friction_models: no rclpy or message imports allowed here (tested)."""
