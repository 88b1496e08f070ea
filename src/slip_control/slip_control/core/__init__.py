"""ROS-free core of slip_control: no rclpy or message imports allowed here (tested)."""
