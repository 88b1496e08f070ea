"""``slip_cli``: command the cell from a shell where the ``ros2`` CLI is not installed.

Cell commands::

    slip_cli force 10                     # grasp with 10 N per finger
    slip_cli estimate linear 1.0          # contact-estimation phase for 1 s
    slip_cli properties                   # latest contact properties
    slip_cli mode linear --distance 0.02 --duration 2.0
    slip_cli mode rotational --angle 0.35 --duration 2.0
    slip_cli run demo --record demo_sim   # an experiment-runner sequence, with progress
    slip_cli lifecycle sim_gripper get

What ``ros2`` offers, for installs without it::

    slip_cli topic list                   # topics with their types
    slip_cli topic hz /finger_1/ft/wrench # rate (--header: from the message stamps)
    slip_cli node list
    slip_cli param list slip_controller
    slip_cli param describe slip_controller hold.margin   # type, description, range
    slip_cli param get slip_controller hold.margin
    slip_cli param set slip_controller hold.margin 2.5
    slip_cli call gripper/bias_ft         # any service; type looked up, response as YAML
    slip_cli call contact/start slip_msgs/srv/StartEstimation '{phase: 1, duration: 1.0}'
    slip_cli echo gripper/status --count 3   # YAML, like ros2 topic echo

Exit code 0 on success, 1 when a command is refused or fails (one line on stderr).
"""
from __future__ import annotations

import argparse
import math
import sys
from typing import Any

import rclpy
from rclpy.action import ActionClient
from rclpy.duration import Duration
from rclpy.signals import SignalHandlerOptions

from slip_bringup import ros_commands
from slip_bringup.cli_session import CliError, CliSession
from slip_cell_common.core import names

MODES = {'off': 0, 'rotational': 1, 'linear': 2, 'hinge': 3, 'hold': 4}
PHASES = {'idle': 0, 'linear': 1, 'rotational': 2, 'limit_surface': 3, 'online': 4}
TRANSITIONS = {'configure': 1, 'cleanup': 2, 'activate': 3, 'deactivate': 4, 'shutdown': 5}


def _finite(value: float, what: str) -> float:
    if not math.isfinite(value):
        raise CliError(f'{what} must be finite, got {value}')
    return value


def cmd_force(cli: CliSession, ns: argparse.Namespace) -> str:
    from slip_cell_common.qos import COMMAND
    from slip_msgs.msg import GraspForceCommand
    pub = cli.node.create_publisher(GraspForceCommand, names.GRASP_FORCE_CMD, COMMAND)
    if not cli.wait(lambda: pub.get_subscription_count() > 0, cli.timeout_s):
        raise CliError(f'no subscriber on {names.GRASP_FORCE_CMD} (is the driver running?)')
    msg = GraspForceCommand(force=_finite(ns.newton, 'force'), timeout=ns.expire,
                            source=GraspForceCommand.SOURCE_MANUAL)
    msg.header.stamp = cli.node.get_clock().now().to_msg()
    pub.publish(msg)
    pub.wait_for_all_acked(Duration(seconds=2.0))  # reliable delivery before the node goes
    return f'commanded {ns.newton:.2f} N'


def cmd_estimate(cli: CliSession, ns: argparse.Namespace) -> str:
    from slip_msgs.srv import StartEstimation
    res = cli.call(StartEstimation, names.CONTACT_START_SRV, StartEstimation.Request(
        phase=PHASES[ns.phase], duration=_finite(ns.duration, 'duration')))
    if not res.accepted:
        raise CliError(f'estimation refused: {res.message}')
    return res.message or 'accepted'


def _format_properties(props: Any) -> str:
    rows = [f'source={props.source} preset={props.preset_name!r} valid={props.valid} '
            f'online_updated={props.online_updated}']
    for k, f in ((1, props.finger_1), (2, props.finger_2)):
        rows.append(f'finger {k}: mu_c={f.mu_c:.4f}±{f.mu_c_std:.4f} mu_s={f.mu_s:.4f} '
                    f'mu_v={f.mu_v:.3f} r={f.r * 1e3:.3f}±{f.r_std * 1e3:.3f} mm u={f.u:.3g} '
                    f'n=({f.n_linear},{f.n_static},{f.n_rotational}) valid=(lin {f.linear_valid},'
                    f' visc {f.viscous_valid}, stat {f.static_valid}, rot {f.rotational_valid})')
    return '\n'.join(rows)


def cmd_properties(cli: CliSession, ns: argparse.Namespace) -> str:
    del ns
    from slip_msgs.srv import GetContactProperties
    res = cli.call(GetContactProperties, names.CONTACT_GET_PROPERTIES_SRV,
                   GetContactProperties.Request())
    return _format_properties(res.properties) + (f'\n{res.message}' if res.message else '')


def cmd_mode(cli: CliSession, ns: argparse.Namespace) -> str:
    from slip_msgs.srv import SetSlipMode
    req = SetSlipMode.Request(mode=MODES[ns.mode], duration=ns.duration, distance=ns.distance,
                              angle=ns.angle, latch_direction=ns.latch)
    req.direction.x, req.direction.y = ns.direction
    res = cli.call(SetSlipMode, names.SLIP_SET_MODE_SRV, req)
    if not res.success:
        raise CliError(f'mode refused: {res.message}')
    return res.message or f'mode {ns.mode}'


def cmd_run(cli: CliSession, ns: argparse.Namespace) -> str:
    from slip_msgs.action import RunExperiment
    client = ActionClient(cli.node, RunExperiment, names.EXPERIMENT_RUN_ACTION)
    if not cli.wait(client.server_is_ready, cli.timeout_s):
        raise CliError(f'{names.EXPERIMENT_RUN_ACTION} is not available (is experiment_runner '
                       'running?)')
    goal = RunExperiment.Goal(mode=ns.mode, duration=ns.duration, distance=ns.distance,
                              angle=ns.angle, recording_name=ns.record or '')

    def feedback(msg: Any) -> None:
        print(f'  [{msg.feedback.elapsed:7.2f} s] {msg.feedback.phase}', flush=True)
    send = client.send_goal_async(goal, feedback_callback=feedback)
    cli.wait(send.done, cli.timeout_s)
    handle = send.result() if send.done() else None
    if handle is None or not handle.accepted:
        raise CliError(f'experiment {ns.mode!r} was not accepted')
    result = handle.get_result_async()
    cli.wait(result.done, ns.run_timeout)
    if not result.done():
        raise CliError(f'experiment {ns.mode!r} did not finish within {ns.run_timeout:.0f} s')
    res = result.result().result
    text = f'{ns.mode}: {res.message}' + (f'\nbag: {res.bag_path}' if res.bag_path else '')
    if not res.success:
        raise CliError(text)
    return text + '\n' + _format_properties(res.estimate)


def cmd_lifecycle(cli: CliSession, ns: argparse.Namespace) -> str:
    from lifecycle_msgs.srv import ChangeState, GetState
    if ns.transition == 'get':
        res = cli.call(GetState, f'{ns.node}/get_state', GetState.Request())
        return f'{ns.node}: {res.current_state.label}'
    req = ChangeState.Request()
    req.transition.id = TRANSITIONS[ns.transition]
    res = cli.call(ChangeState, f'{ns.node}/change_state', req)
    if not res.success:
        raise CliError(f'{ns.node}: transition {ns.transition} failed')
    return f'{ns.node}: {ns.transition} ok'


def build_parser() -> argparse.ArgumentParser:
    """Argument parser of ``slip_cli``."""
    parser = argparse.ArgumentParser(prog='slip_cli', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--timeout', type=float, default=10.0, help='wait for servers [s]')
    sub = parser.add_subparsers(dest='command', required=True)
    p = sub.add_parser('force', help='publish one grasp-force command [N]')
    p.add_argument('newton', type=float)
    p.add_argument('--expire', dest='expire', type=float, default=0.0,
                   help='command expiry [s]; 0 = until replaced')
    p.set_defaults(func=cmd_force)
    p = sub.add_parser('estimate', help='start a contact-estimation phase')
    p.add_argument('phase', choices=list(PHASES))
    p.add_argument('duration', type=float, nargs='?', default=1.0)
    p.set_defaults(func=cmd_estimate)
    p = sub.add_parser('properties', help='print the latest contact properties')
    p.set_defaults(func=cmd_properties)
    p = sub.add_parser('mode', help='switch the slip-controller mode')
    p.add_argument('mode', choices=list(MODES))
    p.add_argument('--duration', type=float, default=0.0, help='[s]')
    p.add_argument('--distance', type=float, default=0.0, help='[m]')
    p.add_argument('--angle', type=float, default=0.0, help='[rad]')
    p.add_argument('--direction', type=float, nargs=2, default=(0.0, 0.0),
                   metavar=('X', 'Y'), help='linear slip direction in gripper_middle')
    p.add_argument('--latch', action='store_true', help='latch the direction from the motion')
    p.set_defaults(func=cmd_mode)
    p = sub.add_parser('run', help='run an experiment-runner sequence')
    p.add_argument('mode')
    p.add_argument('--record', help='bag name (>= 3 characters)')
    p.add_argument('--duration', type=float, default=0.0)
    p.add_argument('--distance', type=float, default=0.0)
    p.add_argument('--angle', type=float, default=0.0)
    p.add_argument('--run-timeout', type=float, default=600.0)
    p.set_defaults(func=cmd_run)
    p = sub.add_parser('lifecycle', help='lifecycle transition or state of a node')
    p.add_argument('node')
    p.add_argument('transition', choices=['get', *TRANSITIONS])
    p.set_defaults(func=cmd_lifecycle)
    ros_commands.add_parsers(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point; exit code 0 on success, 1 on a refused or failed command."""
    ns = build_parser().parse_args(argv)
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    cli = CliSession(ns.timeout)
    try:
        text = ns.func(cli, ns)
        if text:
            print(text)
        return 0
    except CliError as exc:
        print(f'slip_cli: {exc}', file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130
    except Exception as exc:
        print(f'slip_cli: error: {exc!r}', file=sys.stderr)
        return 1
    finally:
        cli.close()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
