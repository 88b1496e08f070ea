# SPDX-License-Identifier: Apache-2.0
"""The gripper as the standard tools see it: ``/tf_static``, ``/tf`` and ``robot_description``.

One object per gripper node (``gripper_driver`` and the simulator's ``sim_gripper``):

* ``robot_description`` (``std_msgs/String``, latched): the URDF of
  `slip_cell_common.core.gripper_urdf` with ``frames.tf_prefix`` on every link and joint;
* ``/tf_static`` (latched): ``tool0 → gripper_base_link → gripper_middle`` and
  ``ft_sensor_k → vel_sensor_k`` (the velocity sensors' mounts: the velocity-sensor nodes
  publish no frames of their own, so no frame is published twice in a graph);
* ``/tf``: ``gripper_middle → ft_sensor_k`` for the measured opening, stamped with the
  telemetry line it comes from, at the joint-state rate. Nothing while the opening is unknown
  (not homed): a frame drawn at a made-up opening would be wrong, not approximate.

The tree is that of `slip_cell_common.core.frames` (ros_interfaces §7), so
``robot_state_publisher`` fed with ``gripper/joint_states`` and this URDF reproduces the same
transforms. The legacy ``slip_msgs/TransformArray`` topics stay for the recorded bags and the
runner's recordings.
"""
from __future__ import annotations

import math

from rclpy.node import Node

from slip_cell_common.core.frames import (
    FrameParams,
    Transform,
    finger_transforms,
    static_transforms,
)
from slip_cell_common.core.gripper_urdf import GripperGeometry, gripper_urdf
from slip_cell_common.tf_conv import Stamp
from slip_cell_common.tf_publishing import TfBroadcaster, publish_robot_description

#: The URDF's default joint limits and visual dimensions.
DEFAULT_GEOMETRY = GripperGeometry()


class GripperModelPublisher:
    """``robot_description`` (latched at construction), static and finger frames.

    Args:
        node: The gripper node (create once per configure; `destroy` on cleanup).
        frames: Frame constants, prefix included.
        geometry: Joint limits and visual dimensions of the URDF.
    """

    def __init__(self, node: Node, frames: FrameParams,
                 geometry: GripperGeometry = DEFAULT_GEOMETRY) -> None:
        self._node = node
        self._frames = frames
        self.urdf = gripper_urdf(frames, geometry)
        self.tf = TfBroadcaster(node)
        self._description = publish_robot_description(node, self.urdf)

    def send_static(self, stamp: Stamp) -> None:
        """Latch the fixed frames on ``/tf_static`` (stamp: node time now)."""
        self.tf.send_static(static_transforms(self._frames), stamp)

    def send_fingers(self, stamp: Stamp, opening: float) -> bool:
        """Publish ``gripper_middle → ft_sensor_k`` for ``opening`` [m]; False (nothing sent)
        while the opening is not finite."""
        if not math.isfinite(opening):
            return False
        self.tf.send(finger_transforms(self._frames, opening), stamp)
        return True

    def send(self, transforms: list[Transform], stamp: Stamp) -> None:
        """Publish other moving frames of the same node on ``/tf`` (the simulator's scene)."""
        self.tf.send(transforms, stamp)

    def destroy(self) -> None:
        """Destroy the three publishers (the node stays)."""
        self.tf.destroy()
        self._node.destroy_publisher(self._description)
