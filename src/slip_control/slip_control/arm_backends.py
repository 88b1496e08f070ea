# SPDX-License-Identifier: Apache-2.0
"""Robot-arm backends of the experiment runner (control_and_estimation §5.1; CE-9).

The runner's step machine (`slip_control.core.sequence_runner.SequenceRunner`) drives the arm
through three calls of the `ArmBackend` seam, each non-blocking: it returns a finished
`CallResult` or a `Pending` that the runner polls.

============================  ==================================================================
``move_gripper``              relative tool motion along a smooth profile, same contract as
                              ``slip_msgs/MoveGripper``: ``lift`` [m, world up], ``lateral``
                              [m, world horizontal in the grasp plane], ``rotation`` [rad about
                              the grasp axis = ``gripper_middle`` +z], ``duration`` [s] > 0.
                              The result's ``until`` is the expected end on the runner's clock;
                              the runner keeps the step busy until then.
``move_to_pickup``            absolute Cartesian move to the pick-up pose (robot ``base``:
                              position [m], intrinsic xyz Euler angles [rad]).
``move_joints``               absolute joint move [rad] in ``duration`` [s].
``ready()``                   ``(ok, text)`` for the ``arm`` diagnostics task.
``fault()``                   '' or a reason to abort a running sequence (an arm fault).
``object_dropped()``          '' or how the backend saw the object leave the grasp; the
                              runner then marks it lost and asks for a re-grasp.
``destroy()``                 release ROS entities.
============================  ==================================================================

Backends:

* ``mock`` (`MockArm`): every motion succeeds at once and is recorded in ``calls``; for tests
  of the sequencing (no physics, no waiting).
* ``sim`` (`SimArm`): the simulated cell's arm interface: ``sim/move_gripper``
  (``slip_msgs/MoveGripper``, returns at once with ``expected_end`` on the sim clock),
  ``sim/reset_scene`` (``slip_msgs/ResetScene``) for ``move_to_pickup`` (the object is stood on
  the table between the open fingers: the simulated equivalent of going to the object), and
  ``sim/state`` (``slip_msgs/SimState``) for ``object_dropped``. The simulated cell has no
  arm joints, so ``move_joints`` succeeds without motion, and no arm faults.
* ``ur`` (`ur_arm`): a real UR arm through ``ur_robot_driver``. **Not implemented yet**:
  constructing it raises `ArmUnavailableError`.
  What a UR backend must implement — the seam, not a fake:

  - ``move_gripper``: read the current tool pose (``tool0`` in ``base``, e.g. from TF or the
    driver's ``/tcp_pose_broadcaster/pose``), add ``lift`` along base +z, ``lateral`` along the
    base horizontal axis of the grasp plane, and ``rotation`` to the first intrinsic-xyz Euler
    angle of the tool orientation (the grasp axis; §5.2), then send one Cartesian waypoint
    of ``duration`` s (``FollowJointTrajectory`` after IK, or the
    ``cartesian_motion_controller``); ``until`` = send time + ``duration`` on the node clock;
    the `Pending` fails when the goal is rejected or aborted.
  - ``move_to_pickup``: one Cartesian waypoint to ``pickup.position``/``pickup.euler_xyz``
    with the motion time ``max(1 s, 4·(5·|Δp| + |Δangle|))`` (`ExperimentRunnerParams
    .motion_duration`).
  - ``move_joints``: one ``FollowJointTrajectory`` point (``reset_joints.*``).
  - ``ready``: controller manager reachable and the trajectory controller active;
    ``fault``: protective or emergency stop, program not running; ``object_dropped``: ''
    (a UR has no drop sensor: the slip controller's "contact lost" is the runner's cue).
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, NoReturn, Protocol

from rclpy.node import Node
from slip_msgs.msg import SimState
from slip_msgs.srv import MoveGripper, ResetScene

from slip_control.core.runner_cell import CallResult, CallReturn
from slip_cell_common.qos import SENSOR_SUB
from slip_cell_common.core import names


class ArmUnavailableError(RuntimeError):
    """The requested arm backend cannot run on this install (message says why)."""


class ServiceCall:
    """A service call as a runner `Pending`: sent as soon as the server is up, never blocking.

    Args:
        client: rclpy service client.
        request: Request message.
        convert: Response → `CallResult`.
    """

    def __init__(self, client: Any, request: Any,
                 convert: Callable[[Any], CallResult]) -> None:
        self._client = client
        self._request = request
        self._convert = convert
        self._future: Any = None
        self._send()

    def _send(self) -> None:
        if self._future is None and self._client.service_is_ready():
            self._future = self._client.call_async(self._request)

    def done(self) -> bool:
        """The response arrived (the request is sent once the server is available)."""
        self._send()
        return self._future is not None and self._future.done()

    def result(self) -> CallResult:
        """The converted response, or a failure naming the service."""
        name = self._client.srv_name
        exc = self._future.exception()
        if exc is not None:
            return CallResult(False, f'service {name} failed: {exc!r}')
        response = self._future.result()
        if response is None:
            return CallResult(False, f'service {name} returned no response')
        return self._convert(response)

    def describe(self) -> str:
        """What the call is waiting for (timeout messages)."""
        name = self._client.srv_name
        if self._future is None:
            return f'service {name} not available'
        return f'no response from service {name}'

    def cancel(self) -> None:
        """Drop the request (the runner gave up on it)."""
        if self._future is not None and not self._future.done():
            self._client.remove_pending_request(self._future)
            self._future.cancel()


class ArmBackend(Protocol):
    """The arm seam of the runner (see the module docstring)."""

    name: str

    def move_gripper(self, lift: float, lateral: float, rotation: float, duration: float,
                     t: float) -> CallReturn:
        """Relative tool motion (m, m, rad, s); ``until`` = expected end [s]."""

    def move_to_pickup(self, position: tuple[float, ...], euler_xyz: tuple[float, ...],
                       t: float) -> CallReturn:
        """Absolute move to the pick-up pose (m, rad; robot ``base``)."""

    def move_joints(self, names: tuple[str, ...], positions: tuple[float, ...],
                    duration: float, t: float) -> CallReturn:
        """Absolute joint move (rad, s)."""

    def ready(self) -> tuple[bool, str]:
        """Whether the arm can take commands, and a one-line status."""

    def fault(self) -> str:
        """'' or the reason the running sequence must stop."""

    def object_dropped(self) -> str:
        """'' or how the object was seen to leave the grasp."""

    def destroy(self) -> None:
        """Release ROS entities."""


@dataclass
class MockArm:
    """Instant, always-successful arm for tests; ``calls`` records every motion."""

    name: str = 'mock'
    calls: list[tuple[str, tuple[Any, ...]]] = field(default_factory=list)

    def move_gripper(self, lift: float, lateral: float, rotation: float, duration: float,
                     t: float) -> CallReturn:
        """Record and succeed at once."""
        self.calls.append(('move_gripper', (lift, lateral, rotation, duration)))
        return CallResult(True, 'mock arm: moved')

    def move_to_pickup(self, position: tuple[float, ...], euler_xyz: tuple[float, ...],
                       t: float) -> CallReturn:
        """Record and succeed at once."""
        self.calls.append(('move_to_pickup', (tuple(position), tuple(euler_xyz))))
        return CallResult(True, 'mock arm: at the pick-up pose')

    def move_joints(self, names: tuple[str, ...], positions: tuple[float, ...],
                    duration: float, t: float) -> CallReturn:
        """Record and succeed at once."""
        self.calls.append(('move_joints', (tuple(names), tuple(positions), duration)))
        return CallResult(True, 'mock arm: joints moved')

    def ready(self) -> tuple[bool, str]:
        """Always ready."""
        return True, 'mock arm (instant, no motion)'

    def fault(self) -> str:
        """Never faults."""
        return ''

    def object_dropped(self) -> str:
        """No object: never dropped."""
        return ''

    def destroy(self) -> None:
        """Nothing to release."""


class SimArm:
    """The simulated cell's arm interface (``sim/move_gripper``, ``sim/reset_scene``).

    Args:
        node: The runner node (clients and the ``sim/state`` subscription live on it).
        clock_tolerance: Largest plausible gap [s] between the reported ``expected_end`` and
            ``t + duration``; a larger gap means the runner is not on the sim clock.
    """

    name = 'sim'

    def __init__(self, node: Node, clock_tolerance: float) -> None:
        self._node = node
        self._tol = clock_tolerance
        self._move = node.create_client(MoveGripper, names.SIM_MOVE_GRIPPER_SRV)
        self._reset = node.create_client(ResetScene, names.SIM_RESET_SCENE_SRV)
        self._state: SimState | None = None
        self._sub = node.create_subscription(SimState, names.SIM_STATE, self._on_state, SENSOR_SUB)

    def _on_state(self, msg: SimState) -> None:
        self._state = msg

    def move_gripper(self, lift: float, lateral: float, rotation: float, duration: float,
                     t: float) -> CallReturn:
        """``sim/move_gripper``; ``until`` = the reported ``expected_end`` (sim clock)."""
        req = MoveGripper.Request(lift=float(lift), lateral=float(lateral),
                                  rotation=float(rotation), duration=float(duration))
        expected = t + duration

        def convert(res: Any) -> CallResult:
            if not res.success:
                return CallResult(False, f'{names.SIM_MOVE_GRIPPER_SRV} refused: {res.message}')
            end = float(res.expected_end)
            if not math.isfinite(end) or abs(end - expected) > self._tol:
                return CallResult(False, (
                    f'{names.SIM_MOVE_GRIPPER_SRV} expected_end = {end:.3f} s is not on this '
                    f'node\'s clock (expected about {expected:.3f} s): run the runner with '
                    'use_sim_time'))
            return CallResult(True, res.message or 'moving', until=end)
        return ServiceCall(self._move, req, convert)

    def move_to_pickup(self, position: tuple[float, ...], euler_xyz: tuple[float, ...],
                       t: float) -> CallReturn:
        """The simulated cell resets its scene: object on the table between the open fingers."""
        del position, euler_xyz, t
        return ServiceCall(self._reset, ResetScene.Request(preset='', object_on_table=True),
                           lambda r: CallResult(bool(r.success), r.message or
                                                'scene reset: object on the table'))

    def move_joints(self, names: tuple[str, ...], positions: tuple[float, ...],
                    duration: float, t: float) -> CallReturn:
        """No arm joints in the simulated cell: nothing to move."""
        del names, positions, duration, t
        return CallResult(True, 'simulated cell: no arm joints, nothing to move')

    def ready(self) -> tuple[bool, str]:
        """Both sim services discovered."""
        missing = [c.srv_name for c in (self._move, self._reset) if not c.service_is_ready()]
        if missing:
            return False, 'waiting for ' + ', '.join(missing)
        return True, 'simulated arm connected'

    def fault(self) -> str:
        """The simulated arm does not fault."""
        return ''

    def object_dropped(self) -> str:
        """'the object was dropped' when ``sim/state`` says so."""
        if self._state is not None and self._state.object_dropped:
            return f'the object was dropped ({names.SIM_STATE}.object_dropped)'
        return ''

    def destroy(self) -> None:
        """Release the clients and the subscription."""
        self._node.destroy_client(self._move)
        self._node.destroy_client(self._reset)
        self._node.destroy_subscription(self._sub)


def ur_arm(node: Node) -> NoReturn:
    """UR arm: not implemented yet (see the module docstring for the seam it must fill).

    Raises:
        ArmUnavailableError: always.
    """
    del node
    raise ArmUnavailableError(
        "arm backend 'ur' is not implemented yet: implement the ArmBackend seam documented in "
        'slip_control.arm_backends (move_gripper, move_to_pickup, move_joints, ready, fault, '
        "object_dropped, destroy) against the UR driver; use arm.backend 'sim' or 'mock' "
        'meanwhile')


def make_arm(backend: str, node: Node, clock_tolerance: float) -> ArmBackend:
    """The backend named by ``arm.backend``.

    Raises:
        ArmUnavailableError: ``ur`` on this install, or an unknown name.
    """
    if backend == 'mock':
        return MockArm()
    if backend == 'sim':
        return SimArm(node, clock_tolerance)
    if backend == 'ur':
        ur_arm(node)
    raise ArmUnavailableError(f'unknown arm backend {backend!r} (mock, sim, ur)')
