# SPDX-License-Identifier: Apache-2.0
"""Helpers for the slip_control core tests: snapshots built from gripper_middle values."""
from __future__ import annotations

from collections.abc import Callable, Iterator

import pytest

from slip_control.core.contact import ContactProperties, ContactSource, FingerContact
from slip_control.core.params import SlipControllerParams
from slip_control.core.signals import SensorSnapshot, TwistSample, WrenchSample
from slip_cell_common.core.frames import FrameParams, planar_from_middle

FRAMES = FrameParams()


def middle_snapshot(stamp: float, *, f: tuple[float, float] = (0.0, 0.0), tz: float = 0.0,
                    v: tuple[float, float] = (0.0, 0.0), omega: float = 0.0,
                    normal: float = 5.0, ft_stamp: float | None = None,
                    v2_stamp: float | None = None,
                    previous: SensorSnapshot | None = None) -> SensorSnapshot:
    """Both fingers seeing the same ``gripper_middle`` force, torque, velocity and rate.

    Built on ``previous`` (as a node's callbacks build on their last snapshot), so the fingers'
    integrated travel carries over from call to call.
    """
    snap = previous if previous is not None else SensorSnapshot()
    for k in (1, 2):
        fx, fy, t = planar_from_middle(FRAMES, k, f[0], f[1], tz)
        snap = snap.with_wrench(k, WrenchSample(fx, fy, -normal, t,
                                                stamp if ft_stamp is None else ft_stamp))
        vx, vy, w = planar_from_middle(FRAMES, k, v[0], v[1], omega)
        s = stamp if (k == 1 or v2_stamp is None) else v2_stamp
        snap = snap.with_twist(k, TwistSample(vx, vy, w, s))
    return snap


class SnapshotStream:
    """`middle_snapshot` with memory: each call builds on the previous snapshot."""

    def __init__(self) -> None:
        self.last: SensorSnapshot | None = None

    def __call__(self, stamp: float, **kw: object) -> SensorSnapshot:
        self.last = middle_snapshot(stamp, previous=self.last, **kw)  # type: ignore[arg-type]
        return self.last


def finger(mu_c: float = 0.4, r: float = 0.005, *, linear_valid: bool = True,
           rotational_valid: bool = True) -> FingerContact:
    """A finger result with the given values and flags."""
    return FingerContact(mu_c=mu_c, mu_s=mu_c, mu_v=0.0, r=r, u=r * r, mu_c_std=0.005,
                         r_std=0.0002, n_linear=50, n_static=5, n_rotational=50,
                         linear_valid=linear_valid, viscous_valid=False, static_valid=True,
                         rotational_valid=rotational_valid)


def props(mu_c: float = 0.4, r: float = 0.005, *,
          source: ContactSource = ContactSource.ESTIMATED, linear_valid: bool = True,
          rotational_valid: bool = True, name: str = '') -> ContactProperties:
    """A two-finger property set with identical fingers."""
    f = finger(mu_c, r, linear_valid=linear_valid, rotational_valid=rotational_valid)
    return ContactProperties(f, f, source, preset_name=name)


@pytest.fixture
def params() -> SlipControllerParams:
    return SlipControllerParams()


@pytest.fixture
def snap() -> Callable[..., SensorSnapshot]:
    """A fresh snapshot stream per test (travel integrates across the test's calls)."""
    return SnapshotStream()


@pytest.fixture
def make_props() -> Callable[..., ContactProperties]:
    return props


@pytest.fixture
def make_finger() -> Callable[..., FingerContact]:
    return finger


# ---------------------------------------------------------------------------------------------
# Node tests: a driver node that plays sensor streams, /clock and contact properties through
# real DDS to nodes under test on the same executor (private context; no mocked rclpy).
# ---------------------------------------------------------------------------------------------

class RosHarness:
    """Test driver: publishers for sensors, ``/clock`` and properties; bounded spinning.

    Args:
        context: Private rclpy context (``ros_context`` fixture).
    """

    def __init__(self, context: object) -> None:
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        from geometry_msgs.msg import TwistStamped, WrenchStamped
        from rosgraph_msgs.msg import Clock
        from slip_cell_common.qos import CLOCK, LATCHED, SENSOR_PUB
        from slip_msgs.msg import ContactProperties as ContactPropertiesMsg
        self.context = context
        self.node = Node('test_driver', context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.nodes: list[object] = []
        self._action_clients: list[object] = []
        self._wrench = [self.node.create_publisher(WrenchStamped, f'finger_{k}/ft/wrench',
                                                   SENSOR_PUB) for k in (1, 2)]
        self._twist = [self.node.create_publisher(TwistStamped, f'finger_{k}/slip/twist',
                                                  SENSOR_PUB) for k in (1, 2)]
        self._clock = self.node.create_publisher(Clock, '/clock', CLOCK)
        self._props = self.node.create_publisher(ContactPropertiesMsg, 'contact/properties',
                                                 LATCHED)
        self.t = 0.0

    def add(self, node: object) -> object:
        """Put a node under test on the executor."""
        self.executor.add_node(node)
        self.nodes.append(node)
        return node

    def action_client(self, action_type: type, name: str) -> object:
        """An ActionClient on the driver node, destroyed in `close` (rclpy does not)."""
        from rclpy.action import ActionClient
        client = ActionClient(self.node, action_type, name)
        self._action_clients.append(client)
        return client

    def spin_until(self, predicate: Callable[[], bool], timeout_s: float = 5.0) -> bool:
        from slip_cell_common.calls import spin_until
        return spin_until(self.executor, predicate, timeout_s, step_s=0.002)

    def spin_for(self, seconds: float) -> None:
        self.spin_until(lambda: False, seconds)

    def call(self, srv_type: type, name: str, request: object, timeout_s: float = 10.0) -> object:
        from slip_cell_common.calls import call_service
        client = self.node.create_client(srv_type, name)
        try:
            return call_service(self.executor, client, request, timeout_s)
        finally:
            self.node.destroy_client(client)

    def collect(self, msg_type: type, topic: str, qos: object = None) -> list[object]:
        """Subscribe and return the list the messages are appended to."""
        from slip_cell_common.qos import SENSOR_SUB
        out: list[object] = []
        self.node.create_subscription(msg_type, topic, out.append,
                                      SENSOR_SUB if qos is None else qos)
        return out

    def node_time(self, node: object) -> float:
        from slip_cell_common.time_conv import clock_seconds
        return clock_seconds(node.get_clock())  # type: ignore[attr-defined]

    def advance(self, t: float) -> None:
        """Publish ``/clock`` = ``t`` [s] and spin until every node under test has it."""
        from rosgraph_msgs.msg import Clock
        from slip_cell_common.time_conv import seconds_to_stamp
        self.t = t
        self._clock.publish(Clock(clock=seconds_to_stamp(t)))
        ok = self.spin_until(lambda: all(self.node_time(n) >= t - 1e-9 for n in self.nodes),
                             5.0)
        assert ok, f'nodes did not receive /clock = {t}'
        for _ in range(2):                 # let timers that became due run
            self.executor.spin_once(timeout_sec=0.0)

    def publish(self, snap: SensorSnapshot, *, wrenches: bool = True,
                twists: bool = True) -> None:
        """Publish a snapshot's samples (finger-1 twist last: it triggers the step)."""
        from slip_control.slip_msgs_conv import twist_to_msg, wrench_to_msg
        if wrenches:
            for k, w in ((1, snap.wrench_1), (2, snap.wrench_2)):
                if w is not None:
                    self._wrench[k - 1].publish(wrench_to_msg(w, f'ft_sensor_{k}'))
        if twists:
            if snap.twist_2 is not None:
                self._twist[1].publish(twist_to_msg(snap.twist_2, 'vel_sensor_2'))
            if snap.twist_1 is not None:
                self._twist[0].publish(twist_to_msg(snap.twist_1, 'vel_sensor_1'))

    def deliver(self, snap: SensorSnapshot, node: object, *, wrenches: bool = True,
                twists: bool = True) -> None:
        """Publish a snapshot's samples and spin until ``node.snapshot`` holds all of them."""
        self.publish(snap, wrenches=wrenches, twists=twists)
        want = []
        if wrenches:
            want += [('wrench_1', snap.wrench_1), ('wrench_2', snap.wrench_2)]
        if twists:
            want += [('twist_1', snap.twist_1), ('twist_2', snap.twist_2)]

        def arrived() -> bool:
            have = node.snapshot  # type: ignore[attr-defined]
            for name, sample in want:
                got = getattr(have, name)
                if sample is not None and (got is None or abs(got.stamp - sample.stamp) > 1e-6):
                    return False
            return True
        assert self.spin_until(arrived, 2.0), f'samples of {self.t:.4f} s not delivered'

    def play(self, snaps: list[SensorSnapshot], node: object, *, wrenches: bool = True,
             twists: bool = True) -> None:
        """Play snapshots in sim time: clock to each finger-1 stamp, publish, wait for delivery.

        ``node`` must expose ``snapshot`` (the node under test's latest samples).
        """
        for s in snaps:
            assert s.twist_1 is not None
            if s.twist_1.stamp > self.t:
                self.advance(s.twist_1.stamp)
            self.deliver(s, node, wrenches=wrenches, twists=twists)

    def publish_properties(self, props: ContactProperties) -> None:
        from slip_cell_common.time_conv import seconds_to_stamp
        from slip_control.slip_msgs_conv import properties_to_msg
        self._props.publish(properties_to_msg(props, seconds_to_stamp(self.t)))

    def close(self) -> None:
        for c in self._action_clients:
            c.destroy()  # type: ignore[attr-defined]
        for n in self.nodes:
            self.executor.remove_node(n)
            n.destroy_node()  # type: ignore[attr-defined]
        self.executor.shutdown()
        self.node.destroy_node()


@pytest.fixture
def harness(ros_context: object) -> Iterator[RosHarness]:
    """A `RosHarness` on the private context; every node added to it is destroyed after."""
    h = RosHarness(ros_context)
    try:
        yield h
    finally:
        h.close()
