"""Entry points for our nodes: clean start, autostart of lifecycle nodes, clean stop.

rclpy's own signal handler shuts the context down on SIGINT, after which a node can no longer
publish its last state. Our SIGINT/SIGTERM handlers only set a flag that the spin loop checks
every 0.1 s (an exception raised from a handler can land inside an rclpy message conversion and
surface as an unrelated RuntimeError). The ``finally`` block then runs with a valid context:
lifecycle nodes get their shutdown transition (drivers command the safe state there), and the
executor is shut down.
"""
from __future__ import annotations

import signal
import sys
from collections.abc import Callable, Sequence

import rclpy
from lifecycle_msgs.msg import State
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor, \
    SingleThreadedExecutor
from rclpy.lifecycle import LifecycleNode, TransitionCallbackReturn
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from slip_cell_common.executor_turn import spin_once_outliving_destruction


class _StopFlag:
    """Set by the SIGINT/SIGTERM handlers; checked by the spin loop."""

    def __init__(self) -> None:
        self.signal_name = ''

    def __call__(self, signum: int, frame: object) -> None:
        self.signal_name = signal.Signals(signum).name


def autostart(node: LifecycleNode) -> bool:
    """Configure then activate ``node`` if its ``autostart`` parameter is true.

    Returns:
        True when the node ended up active (or autostart is off), False when a transition failed
        (the node stays up, unconfigured or inactive, and says why in its log).
    """
    if not node.has_parameter('autostart') or not node.get_parameter('autostart').value:
        return True
    if node.trigger_configure() != TransitionCallbackReturn.SUCCESS:
        node.get_logger().error('autostart: configure failed; node left unconfigured')
        return False
    if node.trigger_activate() != TransitionCallbackReturn.SUCCESS:
        node.get_logger().error('autostart: activate failed; node left inactive')
        return False
    return True


def _lifecycle_state(node: LifecycleNode) -> int:
    return node._state_machine.current_state[0]


def shutdown_lifecycle(node: LifecycleNode) -> None:
    """Run the shutdown transition (deactivate first when active) so devices reach a safe state."""
    state = _lifecycle_state(node)
    if state == State.PRIMARY_STATE_ACTIVE:
        node.trigger_deactivate()
        state = _lifecycle_state(node)
    if state in (State.PRIMARY_STATE_INACTIVE, State.PRIMARY_STATE_UNCONFIGURED):
        node.trigger_shutdown()


def run_nodes(factories: Sequence[Callable[[], Node]], args: list[str] | None = None,
              multithreaded: bool = False) -> int:
    """Create nodes, autostart lifecycle nodes, spin until SIGINT/SIGTERM, stop cleanly.

    Returns:
        Process exit code: 0 on a requested stop, 1 when a node failed to construct or start.
    """
    rclpy.init(args=args if args is not None else sys.argv,
               signal_handler_options=SignalHandlerOptions.NO)
    stop = _StopFlag()
    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGTERM, stop)
    executor = MultiThreadedExecutor() if multithreaded else SingleThreadedExecutor()
    nodes: list[Node] = []
    code = 0
    try:
        for factory in factories:
            node = factory()
            nodes.append(node)
            executor.add_node(node)
        for node in nodes:
            if isinstance(node, LifecycleNode) and not autostart(node):
                code = 1
        # spin_once with a timeout instead of spin(): a graph without timers would otherwise
        # block inside rcl_wait forever and Python could never run our signal handlers.
        while executor.context.ok() and not stop.signal_name:
            spin_once_outliving_destruction(executor, 0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception as exc:
        if nodes:
            nodes[0].get_logger().fatal(f'unhandled error: {exc!r}')
        else:
            print(f'error: {exc}', file=sys.stderr)
        code = 1
    finally:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        for node in reversed(nodes):
            if isinstance(node, LifecycleNode):
                try:
                    shutdown_lifecycle(node)
                except Exception as exc:
                    node.get_logger().error(f'shutdown transition failed: {exc!r}')
        executor.shutdown()
        for node in nodes:
            node.destroy_node()
        rclpy.try_shutdown()
    return code


def run_node(factory: Callable[[], Node], args: list[str] | None = None,
             multithreaded: bool = False) -> int:
    """`run_nodes` for a single node."""
    return run_nodes([factory], args, multithreaded)
