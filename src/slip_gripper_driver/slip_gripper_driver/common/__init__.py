"""Shared rclpy helpers of the cell: QoS profiles, parameters, diagnostics, node entry points."""
