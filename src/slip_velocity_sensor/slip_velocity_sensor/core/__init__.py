"""ROS-free core of slip_velocity_sensor: no rclpy or message imports allowed here (tested)."""
