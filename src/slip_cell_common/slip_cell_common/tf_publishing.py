# SPDX-License-Identifier: Apache-2.0
"""``/tf``, ``/tf_static`` and ``robot_description`` publishing, the way tf2_ros and
robot_state_publisher do it (no tf2_ros needed).

* ``/tf_static``: reliable, transient local, depth 1. Every message carries the *whole* static
  set (a late joiner receives only the last message), so `TfBroadcaster.send_static` merges
  new transforms into what it sent before, keyed by child frame.
* ``/tf``: reliable, volatile, depth 100 (tf2_ros' dynamic broadcaster profile).
* ``robot_description``: ``std_msgs/String`` with the URDF, reliable, transient local, depth 1
  (relative name, so it lands in the node's namespace like robot_state_publisher's).

Topic names ``/tf`` and ``/tf_static`` are absolute on purpose: TF is one tree per ROS graph;
frame prefixes (``tf_prefix``) separate several grippers.
"""
from __future__ import annotations

from collections.abc import Iterable

from geometry_msgs.msg import TransformStamped
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage

from slip_cell_common.core import names
from slip_cell_common.core.frames import Transform
from slip_cell_common.qos import overridable
from slip_cell_common.tf_conv import Stamp, tf_message, transform_stamped_msg

TF_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                    reliability=ReliabilityPolicy.RELIABLE,
                    durability=DurabilityPolicy.VOLATILE)
TF_STATIC_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                           reliability=ReliabilityPolicy.RELIABLE,
                           durability=DurabilityPolicy.TRANSIENT_LOCAL)
ROBOT_DESCRIPTION_QOS = TF_STATIC_QOS


class TfBroadcaster:
    """Publishes core `Transform` sets on ``/tf`` (moving) and ``/tf_static`` (latched).

    Create one per node (the QoS-override parameters of the two topics are declared once).
    Stamps are float seconds on the node clock or ``builtin_interfaces/Time``: the acquisition
    stamp of the data the transforms come from, or the current node time for static ones.
    """

    def __init__(self, node: Node, tf_topic: str = names.TF,
                 tf_static_topic: str = names.TF_STATIC) -> None:
        self._tf = node.create_publisher(TFMessage, tf_topic, TF_QOS,
                                         qos_overriding_options=overridable())
        self._tf_static = node.create_publisher(TFMessage, tf_static_topic, TF_STATIC_QOS,
                                                qos_overriding_options=overridable())
        self._node = node
        self._static: dict[str, TransformStamped] = {}

    def send(self, transforms: Iterable[Transform], stamp: Stamp) -> None:
        """Publish moving transforms on ``/tf`` (one message, every transform at ``stamp``)."""
        msg = tf_message(transforms, stamp)
        if msg.transforms:
            self._tf.publish(msg)

    def send_static(self, transforms: Iterable[Transform], stamp: Stamp) -> None:
        """Add or replace static transforms (by child frame) and re-latch the whole set."""
        for tr in transforms:
            self._static[tr.child] = transform_stamped_msg(tr, stamp)
        self._tf_static.publish(TFMessage(transforms=list(self._static.values())))

    @property
    def static_children(self) -> tuple[str, ...]:
        """Child frames currently latched on ``/tf_static``."""
        return tuple(self._static)

    def destroy(self) -> None:
        """Destroy both publishers (the node stays)."""
        self._node.destroy_publisher(self._tf)
        self._node.destroy_publisher(self._tf_static)


def publish_robot_description(node: Node, urdf: str,
                              topic: str = names.ROBOT_DESCRIPTION) -> Publisher:
    """Latch ``urdf`` on ``topic`` (``std_msgs/String``); keep the returned publisher alive."""
    publisher = node.create_publisher(String, topic, ROBOT_DESCRIPTION_QOS)
    publisher.publish(String(data=urdf))
    return publisher
