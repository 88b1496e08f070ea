"""slip_gripper_driver."""
