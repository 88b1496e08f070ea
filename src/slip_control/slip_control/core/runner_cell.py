# SPDX-License-Identifier: Apache-2.0
"""The cell seam of the experiment runner (control_and_estimation §5).

`CellInterface` is what the runner's step machine (`slip_control.core.sequence_runner`)
drives: gripper, slip controller, estimator, arm and recorder. The ``experiment_runner`` node
implements it with topics, services and the arm backend; the in-process evaluation implements
it on the simulated cell by calling the cores directly. Every method returns either a finished
`CallResult` or a `Pending` (e.g. wrapping an rclpy future); the machine polls
``Pending.done()`` and never blocks. ``CallResult.until`` keeps the step busy until that time
(arm motions report their expected end).

The arm seam (`CellInterface.move_gripper`, same as ``slip_msgs/MoveGripper``): a motion
*relative to the current tool pose*, along a smooth profile, with

* ``lift`` [m]: world-vertical displacement, + up;
* ``lateral`` [m]: world-horizontal displacement in the grasp plane;
* ``rotation`` [rad]: about the grasp axis (``gripper_middle`` +z) — for the UR backend this
  is the first intrinsic-xyz Euler angle of the pick-up orientation (§5.2);
* ``duration`` [s] > 0.

It returns the expected end time. A UR adapter turns each call into one Cartesian waypoint;
``move_to_pickup`` and ``move_joints`` are the two absolute moves (§5.3 ``go_to_object``,
``reset_joints``); a backend that cannot do them (the simulated cell) resets its scene
instead. The machine tracks the offset from the pick-up pose so that "return to the pick-up
pose" is a relative move too.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

from slip_control.core.contact import ContactProperties
from slip_control.core.contact_estimator import EstimationPhase
from slip_control.core.mode_switch import ModeRequest


def describe_read(props: ContactProperties, estimator_message: str) -> str:
    """The message of a ``read_properties`` result: the properties, and for an invalid set
    the estimator's last report (which names the phase and the finger that failed, and why)."""
    if props.valid or not estimator_message:
        return props.describe()
    return f'{props.describe()} (estimator: {estimator_message})'


@dataclass(frozen=True, slots=True)
class CallResult:
    """Outcome of one cell call.

    Attributes:
        ok: The call succeeded.
        message: Why not, or a note.
        until: Keep the step busy until this time [s] (arm motion end), or ``None``.
        value: Payload (``read_properties``: a `ContactProperties`).
    """

    ok: bool
    message: str = ''
    until: float | None = None
    value: Any = None


@runtime_checkable
class Pending(Protocol):
    """An asynchronous call in flight (e.g. an rclpy service future)."""

    def done(self) -> bool:
        """The call has finished."""

    def result(self) -> CallResult:
        """Its outcome (only after `done`)."""

    # Optional (looked up with getattr): ``describe() -> str`` says what the call waits for
    # (used in timeout messages); ``cancel() -> None`` is called when the call is abandoned.


CallReturn = CallResult | Pending


class CellInterface(Protocol):
    """What the experiment runner drives: gripper, slip controller, estimator, arm, recorder.

    All arguments SI; ``t`` is the current time [s] on the runner's clock.
    """

    def command_force(self, force: float, t: float) -> CallReturn:
        """Publish a grasp-force command [N] (per finger; < 0 opens)."""

    def set_slip_mode(self, request: ModeRequest, t: float) -> CallReturn:
        """``SetSlipMode``; a rejection is ``ok = False`` with the controller's message."""

    def execute_slip(self, request: ModeRequest, t: float) -> CallReturn:
        """``ExecuteSlip``: a LINEAR or ROTATIONAL trajectory, finished when it ends.

        ``ok`` is the trajectory's success ("done"); ``value`` is its
        `slip_control.core.controllers.SlipResult` (also when a
        trajectory ran and failed: "velocity stale", "contact lost", …); a refused request is
        ``ok = False`` with the controller's message and no value. A `Pending` may offer
        ``cancel()`` (the runner calls it when it gives up: the controller falls back to HOLD).
        """

    def start_estimation(self, phase: EstimationPhase, duration: float, t: float) -> CallReturn:
        """``StartEstimation`` for ``duration`` [s]."""

    def read_properties(self, t: float) -> CallReturn:
        """``GetContactProperties``; ``value`` = `ContactProperties`."""

    def bias_ft(self, t: float) -> CallReturn:
        """Bias both F/T sensors (gripper open and empty)."""

    def move_gripper(self, lift: float, lateral: float, rotation: float, duration: float,
                     t: float) -> CallReturn:
        """Relative tool motion (see the module docstring); ``until`` = expected end [s]."""

    def move_to_pickup(self, position: tuple[float, ...], euler_xyz: tuple[float, ...],
                       t: float) -> CallReturn:
        """Absolute Cartesian move to the pick-up pose (robot ``base``; m, rad)."""

    def move_joints(self, names: tuple[str, ...], positions: tuple[float, ...],
                    duration: float, t: float) -> CallReturn:
        """Absolute joint move [rad] in ``duration`` [s]."""

    def start_recording(self, name: str, topics: tuple[str, ...], t: float) -> CallReturn:
        """Start the in-process recorder; ``value`` = bag path."""

    def stop_recording(self, t: float) -> CallReturn:
        """Stop the recorder (no-op when not recording)."""
