# SPDX-License-Identifier: Apache-2.0
"""Former name of `slip_gripper_driver.gripper_msgs_conv` (issue 14).

Kept only for ``force_tracking_test`` (another change set) until it imports
`gripper_msgs_conv`; delete this module then.
"""
from slip_gripper_driver.gripper_msgs_conv import grasp_command_msg

__all__ = ['grasp_command_msg']
