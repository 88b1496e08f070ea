"""ROS-free core of slip_gripper_driver: no rclpy or message imports allowed here (tested)."""
