"""``slip_cli``: command the cell from a shell where the ``ros2`` CLI is not installed.

Examples::

    slip_cli force 10                     # grasp with 10 N per finger
    slip_cli call gripper/bias_ft         # any std_srvs/Trigger service
    slip_cli estimate linear 1.0          # contact-estimation phase for 1 s
    slip_cli properties                   # latest contact properties
    slip_cli mode linear --distance 0.02 --duration 2.0
    slip_cli mode rotational --angle 0.35 --duration 2.0
    slip_cli run demo --record demo_sim   # an experiment-runner sequence, with progress
    slip_cli lifecycle sim_gripper get
    slip_cli param get slip_controller hold.margin
    slip_cli param set slip_controller hold.margin 2.5
    slip_cli echo gripper/status --count 3
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from typing import Any

import rclpy
from rclpy.action import ActionClient
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from slip_cell_common.calls import call_service, spin_until

MODES = {'off': 0, 'rotational': 1, 'linear': 2, 'hinge': 3, 'hold': 4}
PHASES = {'idle': 0, 'linear': 1, 'rotational': 2, 'limit_surface': 3, 'online': 4}
TRANSITIONS = {'configure': 1, 'cleanup': 2, 'activate': 3, 'deactivate': 4, 'shutdown': 5}


class CliError(RuntimeError):
    """A command failed; the message is printed and the exit code is 1."""


class _Cli:
    def __init__(self, timeout_s: float) -> None:
        self.node = Node('slip_cli')
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.timeout_s = timeout_s

    def call(self, srv_type: type, name: str, request: Any) -> Any:
        client = self.node.create_client(srv_type, name)
        response = call_service(self.executor, client, request, self.timeout_s)
        if response is None:
            raise CliError(f'service {name} did not answer within {self.timeout_s:.0f} s '
                           '(is the node running on this ROS_DOMAIN_ID?)')
        return response

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()


def _finite(value: float, what: str) -> float:
    if not math.isfinite(value):
        raise CliError(f'{what} must be finite, got {value}')
    return value


def cmd_force(cli: _Cli, ns: argparse.Namespace) -> str:
    from slip_cell_common.qos import COMMAND
    from slip_msgs.msg import GraspForceCommand
    pub = cli.node.create_publisher(GraspForceCommand, 'gripper/grasp_force_cmd', COMMAND)
    if not spin_until(cli.executor, lambda: pub.get_subscription_count() > 0, cli.timeout_s):
        raise CliError('no subscriber on gripper/grasp_force_cmd (is the driver running?)')
    msg = GraspForceCommand(force=_finite(ns.newton, 'force'), timeout=ns.timeout,
                            source=GraspForceCommand.SOURCE_MANUAL)
    msg.header.stamp = cli.node.get_clock().now().to_msg()
    pub.publish(msg)
    spin_until(cli.executor, lambda: False, 0.2)  # let reliable delivery complete
    return f'commanded {ns.newton:.2f} N'


def cmd_call(cli: _Cli, ns: argparse.Namespace) -> str:
    from std_srvs.srv import Trigger
    res = cli.call(Trigger, ns.service, Trigger.Request())
    if not res.success:
        raise CliError(f'{ns.service}: {res.message}')
    return f'{ns.service}: {res.message or "ok"}'


def cmd_estimate(cli: _Cli, ns: argparse.Namespace) -> str:
    from slip_msgs.srv import StartEstimation
    res = cli.call(StartEstimation, 'contact/start', StartEstimation.Request(
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


def cmd_properties(cli: _Cli, ns: argparse.Namespace) -> str:
    del ns
    from slip_msgs.srv import GetContactProperties
    res = cli.call(GetContactProperties, 'contact/get_properties',
                   GetContactProperties.Request())
    return _format_properties(res.properties) + (f'\n{res.message}' if res.message else '')


def cmd_mode(cli: _Cli, ns: argparse.Namespace) -> str:
    from slip_msgs.srv import SetSlipMode
    req = SetSlipMode.Request(mode=MODES[ns.mode], duration=ns.duration, distance=ns.distance,
                              angle=ns.angle, latch_direction=ns.latch)
    req.direction.x, req.direction.y = ns.direction
    res = cli.call(SetSlipMode, 'slip_control/set_mode', req)
    if not res.success:
        raise CliError(f'mode refused: {res.message}')
    return res.message or f'mode {ns.mode}'


def cmd_run(cli: _Cli, ns: argparse.Namespace) -> str:
    from slip_msgs.action import RunExperiment
    client = ActionClient(cli.node, RunExperiment, 'experiment/run')
    if not spin_until(cli.executor, client.server_is_ready, cli.timeout_s):
        raise CliError('experiment/run is not available (is experiment_runner running?)')
    goal = RunExperiment.Goal(mode=ns.mode, duration=ns.duration, distance=ns.distance,
                              angle=ns.angle, recording_name=ns.record or '')

    def feedback(msg: Any) -> None:
        print(f'  [{msg.feedback.elapsed:7.2f} s] {msg.feedback.phase}', flush=True)
    send = client.send_goal_async(goal, feedback_callback=feedback)
    spin_until(cli.executor, send.done, cli.timeout_s)
    handle = send.result() if send.done() else None
    if handle is None or not handle.accepted:
        raise CliError(f'experiment {ns.mode!r} was not accepted')
    result = handle.get_result_async()
    spin_until(cli.executor, result.done, ns.run_timeout)
    if not result.done():
        raise CliError(f'experiment {ns.mode!r} did not finish within {ns.run_timeout:.0f} s')
    res = result.result().result
    text = f'{ns.mode}: {res.message}' + (f'\nbag: {res.bag_path}' if res.bag_path else '')
    if not res.success:
        raise CliError(text)
    return text + '\n' + _format_properties(res.estimate)


def cmd_lifecycle(cli: _Cli, ns: argparse.Namespace) -> str:
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


def _parse_value(text: str) -> Any:
    import yaml
    return yaml.safe_load(text)


def cmd_param(cli: _Cli, ns: argparse.Namespace) -> str:
    from rcl_interfaces.srv import GetParameters, SetParameters
    from rclpy.parameter import Parameter, parameter_value_to_python
    if ns.action == 'get':
        res = cli.call(GetParameters, f'{ns.node}/get_parameters',
                       GetParameters.Request(names=[ns.name]))
        if not res.values or res.values[0].type == 0:
            raise CliError(f'{ns.node} has no parameter {ns.name!r}')
        return f'{ns.name} = {parameter_value_to_python(res.values[0])!r}'
    if ns.value is None:
        raise CliError('param set needs a value')
    param = Parameter(ns.name, value=_parse_value(ns.value)).to_parameter_msg()
    res = cli.call(SetParameters, f'{ns.node}/set_parameters',
                   SetParameters.Request(parameters=[param]))
    if not res.results[0].successful:
        raise CliError(f'{ns.node} refused {ns.name}: {res.results[0].reason}')
    return f'{ns.name} set'


def cmd_echo(cli: _Cli, ns: argparse.Namespace) -> str:
    from slip_bringup.bag_nodes import import_message_type
    from slip_cell_common.qos import SENSOR_SUB
    topic = ns.topic if ns.topic.startswith('/') else '/' + ns.topic
    types: list[str] = []
    spin_until(cli.executor, lambda: bool(types.extend(
        t for n, ts in cli.node.get_topic_names_and_types() if n == topic for t in ts) or types),
        cli.timeout_s)
    if not types:
        raise CliError(f'no publisher of {topic}')
    got: list[Any] = []
    cli.node.create_subscription(import_message_type(types[0]), topic, got.append, SENSOR_SUB)
    start = time.monotonic()
    shown = 0
    while shown < ns.count and time.monotonic() - start < cli.timeout_s + ns.count:
        cli.executor.spin_once(timeout_sec=0.05)
        while got and shown < ns.count:
            print(got.pop(0), flush=True)
            shown += 1
    if shown < ns.count:
        raise CliError(f'received {shown} of {ns.count} messages on {topic}')
    return ''


def build_parser() -> argparse.ArgumentParser:
    """Argument parser of ``slip_cli``."""
    parser = argparse.ArgumentParser(prog='slip_cli', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--timeout', type=float, default=10.0, help='wait for servers [s]')
    sub = parser.add_subparsers(dest='command', required=True)
    p = sub.add_parser('force', help='publish one grasp-force command [N]')
    p.add_argument('newton', type=float)
    p.add_argument('--expire', dest='timeout', type=float, default=0.0,
                   help='command expiry [s]; 0 = until replaced')
    p.set_defaults(func=cmd_force)
    p = sub.add_parser('call', help='call a std_srvs/Trigger service')
    p.add_argument('service')
    p.set_defaults(func=cmd_call)
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
    p = sub.add_parser('param', help='get or set a parameter')
    p.add_argument('action', choices=['get', 'set'])
    p.add_argument('node')
    p.add_argument('name')
    p.add_argument('value', nargs='?')
    p.set_defaults(func=cmd_param)
    p = sub.add_parser('echo', help='print messages of a topic')
    p.add_argument('topic')
    p.add_argument('--count', type=int, default=1)
    p.set_defaults(func=cmd_echo)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point; exit code 0 on success, 1 on a refused or failed command."""
    ns = build_parser().parse_args(argv)
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    cli = _Cli(ns.timeout)
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
    finally:
        cli.close()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
