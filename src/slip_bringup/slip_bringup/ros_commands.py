"""Generic ROS graph commands of ``slip_cli`` (what the ``ros2`` CLI offers, for wheels installs).

``topic list``, ``topic hz``, ``node list``, ``param get/set/list/describe``, ``call`` (any
service, YAML request) and ``echo`` (YAML). Each takes the `CliSession` and the parsed
arguments and returns the text to print, or raises `CliError`.
"""
from __future__ import annotations

import argparse
import itertools
import math
import queue
import statistics
import time
from typing import Any

import yaml

from slip_bringup.cli_session import CliError, CliSession
from slip_bringup.message_yaml import (MessageFieldError, fill_message, import_interface,
                                       message_to_yaml)
from slip_cell_common.offered_qos import publishers_qos, subscription_profile
from slip_cell_common.recorder import is_hidden_topic

PARAMETER_TYPES = {0: 'not set', 1: 'bool', 2: 'integer', 3: 'double', 4: 'string',
                   5: 'byte array', 6: 'bool array', 7: 'integer array', 8: 'double array',
                   9: 'string array'}


def _absolute(name: str) -> str:
    return name if name.startswith('/') else '/' + name


def _node_name(name: str) -> str:
    return _absolute(name).rstrip('/')


def _topic_type(cli: CliSession, topic: str, timeout_s: float) -> str:
    types: list[str] = []

    def found() -> bool:
        types[:] = [t for n, ts in cli.node.get_topic_names_and_types() if n == topic
                    for t in ts]
        return bool(types) and cli.node.count_publishers(topic) > 0
    if not cli.wait(found, timeout_s):
        raise CliError(f'no publisher of {topic} within {timeout_s:.0f} s')
    return types[0]


def _subscribe(cli: CliSession, topic: str, msgtype: str, callback: Any, raw: bool,
               depth: int = 100) -> Any:
    """Subscription that matches the publishers (latched topics deliver their last sample)."""
    msg_class = import_interface(msgtype, 'msg')
    profile = subscription_profile(publishers_qos(cli.node, topic), depth=depth)
    return cli.node.create_subscription(msg_class, topic, callback, profile, raw=raw)


def cmd_topic(cli: CliSession, ns: argparse.Namespace) -> str:
    """``topic list`` (name and type) or ``topic hz TOPIC``."""
    if ns.topic_command == 'list':
        cli.settle_discovery(lambda: frozenset(
            (n, tuple(t)) for n, t in cli.node.get_topic_names_and_types()), ns.discovery,
            min_s=1.5, stable_s=0.5)
        rows = [(name, ', '.join(types)) for name, types in
                sorted(cli.node.get_topic_names_and_types())
                if ns.all or not is_hidden_topic(name)]
        width = max((len(r[0]) for r in rows), default=0)
        return '\n'.join(f'{name:<{width}}  [{types}]' for name, types in rows)
    return _topic_hz(cli, ns)


def _topic_hz(cli: CliSession, ns: argparse.Namespace) -> str:
    topic = _absolute(ns.topic)
    msgtype = _topic_type(cli, topic, cli.timeout_s)
    stamps: queue.SimpleQueue[float] = queue.SimpleQueue()
    if ns.header:
        def on_msg(msg: Any) -> None:
            stamp = msg.header.stamp
            stamps.put(stamp.sec + 1e-9 * stamp.nanosec)
    else:
        def on_msg(msg: Any) -> None:
            del msg
            stamps.put(time.monotonic())
    if ns.header and not hasattr(import_interface(msgtype, 'msg')(), 'header'):
        raise CliError(f'{msgtype} has no header; measure receive times (omit --header)')
    sub = _subscribe(cli, topic, msgtype, on_msg, raw=not ns.header)
    times: list[float] = []
    deadline = time.monotonic() + ns.duration
    next_report = time.monotonic() + 1.0
    try:
        while time.monotonic() < deadline and (not ns.count or len(times) < ns.count):
            try:
                times.append(stamps.get(timeout=0.05))
            except queue.Empty:
                pass
            if ns.verbose and time.monotonic() >= next_report and len(times) >= 2:
                next_report += 1.0
                print(_rate_text(times[-ns.window:] if ns.window else times), flush=True)
    finally:
        cli.node.destroy_subscription(sub)
    if len(times) < 2:
        raise CliError(f'received {len(times)} message(s) on {topic} in {ns.duration:.1f} s; '
                       'no rate')
    return f'{topic} [{msgtype}] ' + ('header stamps' if ns.header else 'receive times') + \
        '\n' + _rate_text(times[-ns.window:] if ns.window else times)


def _rate_text(times: list[float]) -> str:
    periods = [b - a for a, b in itertools.pairwise(times)]
    span = times[-1] - times[0]
    rate = (len(times) - 1) / span if span > 0 else math.inf
    std = statistics.pstdev(periods) if len(periods) > 1 else 0.0
    return (f'average rate: {rate:.3f}\n\tmin: {min(periods):.6f}s max: {max(periods):.6f}s '
            f'std dev: {std:.6f}s window: {len(times)}')


def cmd_node(cli: CliSession, ns: argparse.Namespace) -> str:
    """``node list``: fully qualified names (hidden nodes with ``--all``)."""
    own = cli.node.get_fully_qualified_name()

    def others() -> frozenset[str]:
        return frozenset(_node_name(f'{space.rstrip("/")}/{name}')
                         for name, space in cli.node.get_node_names_and_namespaces()) - {own}
    fqns = sorted(cli.settle_discovery(others, ns.discovery))
    return '\n'.join(n for n in fqns if ns.all or not n.rsplit('/', 1)[-1].startswith('_'))


def _parameter_value(value: Any) -> Any:
    from rclpy.parameter import parameter_value_to_python
    return parameter_value_to_python(value)


def _describe(descriptor: Any) -> str:
    lines = [f'Parameter name: {descriptor.name}',
             f'  Type: {PARAMETER_TYPES.get(descriptor.type, descriptor.type)}']
    if descriptor.description:
        lines.append(f'  Description: {descriptor.description}')
    lines.append('  Constraints:')
    if descriptor.read_only:
        lines.append('    Read only: true')
    if descriptor.dynamic_typing:
        lines.append('    Dynamic typing: true')
    for rng in list(descriptor.floating_point_range) + list(descriptor.integer_range):
        lines += [f'    Min value: {rng.from_value}', f'    Max value: {rng.to_value}']
        if rng.step:
            lines.append(f'    Step: {rng.step}')
    if descriptor.additional_constraints:
        lines.append(f'    Additional constraints: {descriptor.additional_constraints}')
    if lines[-1] == '  Constraints:':
        lines.append('    (none)')
    return '\n'.join(lines)


def cmd_param(cli: CliSession, ns: argparse.Namespace) -> str:
    """``param get|set|list|describe NODE [NAME [VALUE]]``."""
    from rcl_interfaces.srv import (DescribeParameters, GetParameters, ListParameters,
                                    SetParameters)
    from rclpy.parameter import Parameter
    node = _node_name(ns.node)
    if ns.action == 'list':
        res = cli.call(ListParameters, f'{node}/list_parameters',
                       ListParameters.Request(prefixes=[ns.name] if ns.name else []))
        return '\n'.join(sorted(res.result.names))
    if not ns.name:
        raise CliError(f'param {ns.action} needs a parameter name')
    if ns.action == 'describe':
        res = cli.call(DescribeParameters, f'{node}/describe_parameters',
                       DescribeParameters.Request(names=[ns.name]))
        if not res.descriptors or res.descriptors[0].type == 0:
            raise CliError(f'{node} has no parameter {ns.name!r}')
        return _describe(res.descriptors[0])
    if ns.action == 'get':
        res = cli.call(GetParameters, f'{node}/get_parameters',
                       GetParameters.Request(names=[ns.name]))
        if not res.values or res.values[0].type == 0:
            raise CliError(f'{node} has no parameter {ns.name!r}')
        return f'{ns.name} = {_parameter_value(res.values[0])!r}'
    if ns.value is None:
        raise CliError('param set needs a value')
    param = Parameter(ns.name, value=yaml.safe_load(ns.value)).to_parameter_msg()
    res = cli.call(SetParameters, f'{node}/set_parameters',
                   SetParameters.Request(parameters=[param]))
    if not res.results[0].successful:
        raise CliError(f'{node} refused {ns.name}: {res.results[0].reason}')
    return f'{ns.name} set'


def _service_type(cli: CliSession, service: str) -> str:
    types: list[str] = []

    def found() -> bool:
        types[:] = [t for n, ts in cli.node.get_service_names_and_types() if n == service
                    for t in ts]
        return bool(types)
    if not cli.wait(found):
        raise CliError(f'service {service} is not available after {cli.timeout_s:.0f} s '
                       '(is the node running on this ROS_DOMAIN_ID?)')
    return types[0]


def _looks_like_type(text: str) -> bool:
    return '/' in text and not any(c in text for c in '{}:[] ')


def cmd_call(cli: CliSession, ns: argparse.Namespace) -> str:
    """``call SERVICE [TYPE] [YAML]``: any service; the type is looked up when omitted.

    The response is printed as YAML; a response whose ``success`` field is false fails.
    """
    service = _absolute(ns.service)
    if ns.type and ns.values is None and not _looks_like_type(ns.type):
        ns.type, ns.values = None, ns.type  # call SERVICE 'YAML' (type looked up)
    srv_name = ns.type or _service_type(cli, service)
    try:
        srv = import_interface(srv_name, 'srv')
        args = yaml.safe_load(ns.values) if ns.values else None
        request = fill_message(srv.Request(), args)
    except (MessageFieldError, yaml.YAMLError) as exc:
        raise CliError(str(exc).replace('\n', ' ')) from None
    response = cli.call(srv, service, request)
    text = f'{service} [{srv_name}] response:\n' + message_to_yaml(response).rstrip()
    if getattr(response, 'success', True) is False:
        raise CliError(text)
    return text


def cmd_echo(cli: CliSession, ns: argparse.Namespace) -> str:
    """``echo TOPIC [--count N]``: messages as YAML documents (``---`` between them)."""
    topic = _absolute(ns.topic)
    msgtype = _topic_type(cli, topic, cli.timeout_s)
    got: queue.SimpleQueue[Any] = queue.SimpleQueue()
    sub = _subscribe(cli, topic, msgtype, got.put, raw=False, depth=max(10, ns.count))
    shown = 0
    deadline = time.monotonic() + cli.timeout_s + ns.count
    try:
        while shown < ns.count and time.monotonic() < deadline:
            try:
                msg = got.get(timeout=0.05)
            except queue.Empty:
                continue
            print(message_to_yaml(msg) + '---', flush=True)
            shown += 1
    finally:
        cli.node.destroy_subscription(sub)
    if shown < ns.count:
        raise CliError(f'received {shown} of {ns.count} messages on {topic}')
    return ''


def add_parsers(sub: Any) -> None:
    """Add the generic commands to ``slip_cli``'s sub-parsers."""
    p = sub.add_parser('topic', help='topic list (with types) | topic hz TOPIC')
    tsub = p.add_subparsers(dest='topic_command', required=True)
    q = tsub.add_parser('list', help='topics and their types')
    q.add_argument('--all', action='store_true', help='also hidden topics')
    q.add_argument('--discovery', type=float, default=5.0,
                   help='longest discovery wait [s] (ends earlier once the graph is stable)')
    q = tsub.add_parser('hz', help='message rate of a topic')
    q.add_argument('topic')
    q.add_argument('--duration', type=float, default=5.0, help='measure this long [s]')
    q.add_argument('--count', type=int, default=0, help='stop after N messages (0: duration)')
    q.add_argument('--window', type=int, default=0, help='last N messages only (0: all)')
    q.add_argument('--header', action='store_true',
                   help="use the messages' header stamps instead of receive times")
    q.add_argument('--verbose', action='store_true', help='print a report every second')
    p.set_defaults(func=cmd_topic)
    p = sub.add_parser('node', help='node list')
    nsub = p.add_subparsers(dest='node_command', required=True)
    q = nsub.add_parser('list', help='fully qualified node names')
    q.add_argument('--all', action='store_true', help='also hidden nodes')
    q.add_argument('--discovery', type=float, default=5.0,
                   help='longest discovery wait [s] (ends earlier once the graph is stable)')
    p.set_defaults(func=cmd_node)
    p = sub.add_parser('param', help='get | set | list | describe parameters of a node')
    p.add_argument('action', choices=['get', 'set', 'list', 'describe'])
    p.add_argument('node')
    p.add_argument('name', nargs='?', help='parameter (list: optional prefix)')
    p.add_argument('value', nargs='?', help='YAML value (set)')
    p.set_defaults(func=cmd_param)
    p = sub.add_parser('call', help="call any service: call SERVICE [TYPE] ['YAML request']")
    p.add_argument('service')
    p.add_argument('type', nargs='?', help='pkg/srv/Name (default: looked up in the graph)')
    p.add_argument('values', nargs='?', help="request fields as YAML, e.g. '{phase: 1}'")
    p.set_defaults(func=cmd_call)
    p = sub.add_parser('echo', help='print messages of a topic as YAML')
    p.add_argument('topic')
    p.add_argument('--count', type=int, default=1)
    p.set_defaults(func=cmd_echo)
