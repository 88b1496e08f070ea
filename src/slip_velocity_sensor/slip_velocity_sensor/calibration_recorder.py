# SPDX-License-Identifier: Apache-2.0
"""``calibration_recorder``: run the stop-to-stop procedure and record it to bags.

Procedure (hardware_protocols §3.7), per chip and axis of one sensor, with the
``velocity_sensor`` node of that finger running::

    calibration_recorder --finger 1 --chips 1 2 3 --axes x y --output-dir calib/

1. Asks the operator to align the rail with the chip axis under test (Enter to start;
   ``--yes`` skips the question).
2. Starts recording ``finger_k/slip/chips``, ``finger_k/slip/twist``, ``finger_k/slip/state``
   and ``/diagnostics`` to the bag ``<output-dir>/Sensor<N>chip<k><x|y>`` (MCAP, rosbag2
   version 9), switches the sensor to single-chip mode ``k`` (``finger_k/slip/set_chip_mode``).
3. Prints the timed prompts of the procedure (rest, get ready, GO: traverse in T s, ...;
   12 traverses, 13 rests, about 2 min), timed with the node clock.
4. Switches back to fused mode (also on Ctrl-C or an error) and closes the bag.

Then fit all recordings with ``calibration_fit fit <output-dir> --out-dir <dir>``, which reads
these bags as well as CSV files.
"""
from __future__ import annotations

import argparse
import itertools
import sys
from pathlib import Path
from typing import Any
from collections.abc import Callable, Sequence

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import remove_ros_args
from slip_msgs.srv import SetChipMode

from slip_cell_common.bag_io import bag_info
from slip_cell_common.calls import call_service, spin_until
from slip_cell_common.core import names
from slip_cell_common.recorder import TopicRecorder
from slip_cell_common.time_conv import clock_seconds
from slip_velocity_sensor.core.procedure import (ProcedureParams, prompt_schedule, schedule,
                                                 scaled)

RECORDED = ('chips', 'twist', 'state')


class RecorderError(RuntimeError):
    """The procedure cannot run (service or topic missing, chip mode refused)."""


def recording_name(sensor: int, chip: int, axis: str) -> str:
    """Recording name of the spec: ``Sensor<N>chip<k><x|y>``."""
    return f'Sensor{sensor}chip{chip}{axis}'


class CalibrationRecorder:
    """Runs the procedure on one finger's sensor (a plain node driven by its own executor).

    Args:
        node: Node for the service client and the recorder subscriptions.
        executor: Executor spinning ``node``.
        finger: Finger number k (topic and service names ``finger_k/slip/...``).
        procedure: Procedure timing.
        say: Output of prompts and status lines.
        service_timeout: Longest wait for the chip-mode service [s].
        warn_before: Lead of the "get ready" prompt [s].
    """

    def __init__(self, node: Node, executor: SingleThreadedExecutor, finger: int,
                 procedure: ProcedureParams, say: Callable[[str], None],
                 service_timeout: float = 10.0, warn_before: float = 3.0) -> None:
        self.node = node
        self.executor = executor
        self.finger = finger
        self.procedure = procedure
        self.say = say
        self.service_timeout = service_timeout
        self.warn_before = warn_before
        base = names.slip_base(finger)
        self.topics = {name: node.resolve_topic_name(f'{base}/{name}') for name in RECORDED}
        self.service_name = node.resolve_topic_name(names.slip_set_chip_mode_srv(finger))
        self._client = node.create_client(SetChipMode, names.slip_set_chip_mode_srv(finger))

    def _now(self) -> float:
        return clock_seconds(self.node.get_clock())

    def set_chip_mode(self, chip: int) -> None:
        """Call the chip-mode service; raises `RecorderError` unless it succeeded."""
        response: Any = call_service(self.executor, self._client, SetChipMode.Request(chip=chip),
                                     self.service_timeout)
        if response is None:
            raise RecorderError(f'{self.service_name}: no response within '
                                f'{self.service_timeout:g} s (is velocity_sensor_{self.finger} '
                                'running and active?)')
        if not response.success:
            raise RecorderError(f'{self.service_name}: chip {chip} refused: {response.message}')
        self.say(f'chip mode {chip}: {response.message}')

    def record(self, bag: Path, chip: int) -> Path:
        """Record one chip-axis recording to the new bag ``bag``; returns its path.

        The chip mode is back to fused when this returns or raises.
        """
        recorder = TopicRecorder(self.node, bag, topics=tuple(self.topics.values()))
        try:
            if not spin_until(self.executor, lambda: self.topics['chips'] in recorder.topics,
                              self.service_timeout):
                raise RecorderError(f'topic {self.topics["chips"]} not found within '
                                    f'{self.service_timeout:g} s (velocity_sensor_{self.finger} '
                                    'not configured?)')
            self.set_chip_mode(chip)
            try:
                self._run_prompts()
            finally:
                self.set_chip_mode(0)
            spin_until(self.executor, lambda: False, 0.2)  # let the last messages arrive
        finally:
            path = recorder.stop()
        return path

    def _run_prompts(self) -> None:
        steps = schedule(self.procedure)
        t0 = self._now()
        for prompt in prompt_schedule(steps, self.warn_before):

            def due(t: float = prompt.t) -> bool:
                return self._now() - t0 >= t

            spin_until(self.executor, due, prompt.t + 60.0)
            self.say(f'[{prompt.t:6.1f} s] {prompt.text}')


def _chips_count(bag: Path, topic: str) -> int:
    return sum(t.count for t in bag_info(bag).topics if t.name == topic)


def _parse_args(argv: Sequence[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog='calibration_recorder',
                                     description=__doc__.split('\n')[0].strip('`: '))
    parser.add_argument('--finger', type=int, choices=(1, 2), required=True,
                        help='finger whose velocity_sensor node is used')
    parser.add_argument('--sensor', type=int, default=0,
                        help='sensor number N in the recording names (default: the finger)')
    parser.add_argument('--chips', type=int, nargs='+', choices=(1, 2, 3), default=[1, 2, 3])
    parser.add_argument('--axes', nargs='+', choices=('x', 'y'), default=['x', 'y'])
    parser.add_argument('--output-dir', required=True, help='directory of the bags')
    parser.add_argument('--distance', type=float, default=ProcedureParams().distance,
                        help='distance between the hard stops [m] (shown in the summary)')
    parser.add_argument('--time-scale', type=float, default=1.0,
                        help='multiply every duration (rehearsal; 1 = the spec procedure)')
    parser.add_argument('--warn-before', type=float, default=3.0,
                        help='"get ready" lead before each traverse [s]')
    parser.add_argument('--service-timeout', type=float, default=10.0, help='[s]')
    parser.add_argument('--yes', action='store_true',
                        help='do not wait for Enter before each recording')
    return parser.parse_args(argv)


def _say(text: str) -> None:
    print(text, flush=True)


def main(argv: Sequence[str] | None = None) -> int:
    """Console script ``calibration_recorder``."""
    full = list(sys.argv if argv is None else ['calibration_recorder', *argv])
    args = _parse_args(remove_ros_args(full)[1:])
    procedure = scaled(ProcedureParams(distance=args.distance), args.time_scale)
    out_dir = Path(args.output_dir)
    sensor = args.sensor or args.finger
    jobs = list(itertools.product(args.chips, args.axes))
    existing = [recording_name(sensor, c, a) for c, a in jobs
                if (out_dir / recording_name(sensor, c, a)).exists()]
    if existing:
        print(f'error: {out_dir} already holds {existing}; choose another --output-dir',
              file=sys.stderr)
        return 2
    context = Context()
    rclpy.init(args=full, context=context, signal_handler_options=SignalHandlerOptions.NO)
    node = Node('calibration_recorder', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    code = 0
    try:
        rec = CalibrationRecorder(node, executor, args.finger, procedure, _say,
                                  args.service_timeout, args.warn_before)
        for chip, axis in jobs:
            name = recording_name(sensor, chip, axis)
            if not args.yes:
                input(f'\n{name}: align the rail with chip {chip} '
                      f'{"tangential (x)" if axis == "x" else "radial (y)"} axis, surface at '
                      'the near stop; press Enter to start ')
            _say(f'{name}: recording to {out_dir / name}')
            path = rec.record(out_dir / name, chip)
            count = _chips_count(path, rec.topics['chips'])
            _say(f'{name}: {count} single-chip samples in {path}')
            if count == 0:
                _say(f'{name}: WARNING: no samples on {rec.topics["chips"]}; is the node active?')
                code = 1
        _say(f'done; fit with: calibration_fit fit {out_dir} --out-dir <dir> '
             f'--distance {args.distance:g}')
    except RecorderError as exc:
        print(f'error: {exc}', file=sys.stderr)
        code = 1
    except (KeyboardInterrupt, EOFError):
        print('\ninterrupted; sensor back in fused mode, bag closed', file=sys.stderr)
        code = 130
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    return code


if __name__ == '__main__':
    sys.exit(main())
