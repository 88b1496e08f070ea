# SPDX-License-Identifier: Apache-2.0
"""``force_tracking_test``: play the force-tracking profile and analyse the recording.

``force_tracking_test run`` publishes the profile of control_and_estimation §5.4
(`slip_cell_common.core.force_profile.ForceTrackingProfile`, the one profile, which the
experiment runner's ``force_tracking_test`` mode plays too: 5 N, the square wave, the 1–64 Hz
sines, 5 N, then 0 N) on ``gripper/grasp_force_cmd`` at 500 Hz with ``SOURCE_TEST``, records
the command, ``gripper/motor_command``, ``gripper/status`` and ``finger_1/ft/wrench`` to a bag
(`common.recorder.TopicRecorder`) and prints rise time, overshoot, settling time and the −3 dB
bandwidth (§6.1, §6.2). ``force_tracking_test analyze BAG`` prints the same report from a bag.

Measured force = −Fz of finger 1 (bias removed); target = the published command, or
``gripper/motor_command.force_target`` when the bag has no command topic. The gripper must
hold an object, be armed and have its F/T biased (``slip_cli call gripper/bias_ft``).

    force_tracking_test run --bag bags/sponge_1
    force_tracking_test analyze bags/sponge_1
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Any
from collections.abc import Sequence

import numpy as np

from slip_cell_common.bag_io import BagError, read_messages, stamp_s
from slip_cell_common.core import names
from slip_cell_common.core.cli_args import (Parser, finite_float, non_negative_float,
                                            plain_doc, positive_float)
from slip_cell_common.time_conv import clock_seconds
from slip_cell_common.core.force_profile import ForceTrackingProfile
from slip_gripper_driver.core.force_tracking import ForceTrackingReport, analyze, format_report

COMMAND_TOPIC = names.GRASP_FORCE_CMD
MOTOR_TOPIC = names.MOTOR_COMMAND
WRENCH_TOPIC = names.ft_wrench(1)
STATUS_TOPIC = names.GRIPPER_STATUS
RECORDED = (COMMAND_TOPIC, MOTOR_TOPIC, WRENCH_TOPIC, STATUS_TOPIC)


def analyze_bag(path: Path | str, profile: ForceTrackingProfile = ForceTrackingProfile(),
                t0: float | None = None) -> ForceTrackingReport:
    """Report of one recorded run (header stamps).

    Raises:
        BagError: The bag is missing, corrupt or lacks the measured wrench.
        ValueError: The recording does not cover the profile.
    """
    messages = read_messages(path)
    bare = {topic.lstrip('/'): items for topic, items in messages.items()}
    wrench = bare.get(WRENCH_TOPIC, [])
    if not wrench:
        raise BagError(f'bag {path} has no {WRENCH_TOPIC} messages')
    command = bare.get(COMMAND_TOPIC, [])
    if command:
        t_target = np.array([stamp_s(m) for _, m in command])
        target = np.array([m.force for _, m in command])
    else:
        motor = bare.get(MOTOR_TOPIC, [])
        if not motor:
            raise BagError(f'bag {path} has neither {COMMAND_TOPIC} nor {MOTOR_TOPIC}')
        t_target = np.array([stamp_s(m) for _, m in motor])
        target = np.array([m.force_target for _, m in motor])
    t_meas = np.array([stamp_s(m) for _, m in wrench])
    measured = np.array([-m.wrench.force.z for _, m in wrench])
    return analyze(t_target, target, t_meas, measured, profile=profile, t0=t0)


def run_profile(node: Any, executor: Any, profile: ForceTrackingProfile, *,
                bag: Path | None, duration_s: float, timeout_s: float,
                wait_s: float = 10.0) -> Path | None:
    """Publish the profile from ``node`` (an rclpy Node spun by ``executor``) and record.

    Args:
        node: The tool's node.
        executor: Executor spinning ``node``.
        profile: Profile to play.
        bag: New bag directory, or None to not record.
        duration_s: Played part of the profile [s] (≤ its duration), then ``final_force``.
        timeout_s: ``GraspForceCommand.timeout`` of every command [s].
        wait_s: Longest wait for a subscriber of the command topic [s].

    Returns:
        The bag path (None when not recording).

    Raises:
        RuntimeError: Nobody subscribes to the command topic within ``wait_s``.
    """
    from slip_msgs.msg import GraspForceCommand

    from slip_gripper_driver import ros_conv
    from slip_cell_common.calls import spin_until
    from slip_cell_common.qos import COMMAND
    from slip_cell_common.recorder import TopicRecorder

    pub = node.create_publisher(GraspForceCommand, COMMAND_TOPIC, COMMAND)
    if not spin_until(executor, lambda: pub.get_subscription_count() > 0, wait_s):
        raise RuntimeError(f'no subscriber on {COMMAND_TOPIC} after {wait_s:.0f} s '
                           '(is gripper_driver running?)')
    recorder = TopicRecorder(node, bag, topics=RECORDED) if bag is not None else None
    if recorder is not None:  # let the recorder discover and match the topics first
        spin_until(executor, lambda: len(recorder.topics) >= 3, 2.0)
    clock = node.get_clock()
    t0 = clock_seconds(clock)
    state = {'done': False}

    def tick() -> None:
        t = clock_seconds(clock)
        elapsed = t - t0
        if elapsed >= duration_s:
            force = profile.final_force
            state['done'] = True
        else:
            force = profile.target(elapsed)
        pub.publish(ros_conv.grasp_command_msg(t, force, timeout_s,
                                               GraspForceCommand.SOURCE_TEST))

    timer = node.create_timer(1.0 / profile.rate_hz, tick)
    spin_until(executor, lambda: state['done'], duration_s + 30.0, step_s=0.001)
    node.destroy_timer(timer)
    end = time.monotonic() + 0.3  # trailing messages
    spin_until(executor, lambda: time.monotonic() > end, 1.0)
    if recorder is None:
        return None
    return recorder.stop()


def _cmd_run(args: argparse.Namespace, ros_args: list[str]) -> int:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    profile = ForceTrackingProfile()
    duration = profile.duration
    if args.duration > 0.0:
        duration = min(args.duration, profile.duration)
    bag = None if args.no_record else Path(args.bag or time.strftime(
        'bags/force_tracking_%Y%m%d_%H%M%S'))
    rclpy.init(args=ros_args)
    node = Node('force_tracking_test')
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        print(f'playing {duration:.1f} s of the force-tracking profile on {COMMAND_TOPIC}'
              + (f', recording to {bag}' if bag else ''), flush=True)
        path = run_profile(node, executor, profile, bag=bag, duration_s=duration,
                           timeout_s=args.timeout, wait_s=args.wait)
    except (RuntimeError, BagError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print('interrupted', file=sys.stderr)
        return 130
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    if path is None:
        return 0
    print(f'recorded {path}')
    return _report(path, None)


def _report(path: Path | str, t0: float | None) -> int:
    try:
        report = analyze_bag(path, t0=t0)
    except BagError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 1
    except ValueError as exc:
        print(f'error: {path}: the recording does not cover the profile ({exc})',
              file=sys.stderr)
        return 1
    print(format_report(report))
    return 0 if math.isfinite(report.step.rise_time) else 2


def main(argv: Sequence[str] | None = None) -> int:
    """Console entry point ``force_tracking_test``."""
    from rclpy.utilities import remove_ros_args

    full = list(sys.argv if argv is None else ['force_tracking_test', *argv])
    parser = Parser(prog='force_tracking_test', description=plain_doc(__doc__))
    sub = parser.add_subparsers(dest='command', metavar='COMMAND', required=True,
                                help='run the test or analyse a recording (COMMAND --help for '
                                     'its options)')
    run = sub.add_parser('run', help='publish the profile, record and analyse',
                         description='Play the force-tracking profile on '
                                     'gripper/grasp_force_cmd at 500 Hz, record, and print the '
                                     'report. Extra --ros-args are passed to the node.')
    run.add_argument('--bag', default='', metavar='DIR',
                     help='bag directory to create (default: bags/force_tracking_<time>)')
    run.add_argument('--no-record', action='store_true',
                     help='only publish the profile (no bag, no report)')
    run.add_argument('--duration', type=non_negative_float, default=0.0, metavar='S',
                     help='play only the first S seconds (0 = the whole profile)')
    run.add_argument('--timeout', type=non_negative_float, default=0.1, metavar='S',
                     help='GraspForceCommand.timeout of each command [s] (0 = valid until '
                          'replaced)')
    run.add_argument('--wait', type=positive_float, default=10.0, metavar='S',
                     help='longest wait for gripper_driver to subscribe [s]')
    ana = sub.add_parser('analyze', help='analyse a recorded bag',
                         description='Print rise time, t50, overshoot, settling time, the '
                                     'frequency response and the -3 dB bandwidth of a recorded '
                                     'run.')
    ana.add_argument('bag', help='bag directory')
    ana.add_argument('--t0', type=finite_float, default=None, metavar='S',
                     help='profile start on the bag clock [s] (default: detected from the '
                          'first rise of the command)')
    args = parser.parse_args(remove_ros_args(full)[1:])
    if args.command == 'analyze':
        return _report(args.bag, args.t0)
    return _cmd_run(args, full)


if __name__ == '__main__':
    sys.exit(main())
