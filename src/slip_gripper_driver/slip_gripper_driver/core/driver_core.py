# SPDX-License-Identifier: Apache-2.0
"""A gripper bridge wired to its serial port: what the ``gripper_driver`` node wraps (ROS-free).

`GripperDriverCore` connects a `bridge.GripperBridge` to a
`slip_cell_common.core.serial_transport.SerialLink` (port, reader thread, reconnection with
back-off), runs the link watchdog on a thread of its own and exposes the lifecycle steps a
node needs. The 500 Hz loop runs on the link's reader thread: the lines of each read go
through `GripperBridge.on_lines` (a backlog is stamped one firmware period apart and only its
newest line steps and writes), which writes the command before ``on_result`` sees the line.

Every event carries a message that states what the driver did (`EVENT_TEXT`): a stale link
holds the last command or writes the safe voltage (``link.stale_action``) and stays armed,
only a link fault (or a loop stuck beyond ``link.host_stall_limit`` while the rest of the
driver runs) disarms, and a host stall with telemetry waiting (even a pause of the whole
process) changes nothing on the device.
"""
from __future__ import annotations

import threading
from collections.abc import Callable

from slip_cell_common.core.serial_transport import (ByteStream, Clock, LinkError, LinkStats,
                                                    ReconnectParams, SerialLink, open_stream)
from slip_gripper_driver.core.bridge import GripperBridge
from slip_gripper_driver.core.bridge_params import BridgeParams
from slip_gripper_driver.core.gripper_records import LineResult, LinkState, WatchdogResult
from slip_gripper_driver.core.protocol import TELEMETRY_PERIOD_S

LineResultCallback = Callable[[LineResult], None]
EventCallback = Callable[[float, str, str], None]
#: ``(t, result)`` after each watchdog check, on the watchdog thread.
WatchdogCallback = Callable[[float, WatchdogResult], None]

#: What the driver did, per line event (appended to the port name in the event message).
EVENT_TEXT = {
    'firmware_restart': "firmware restarted ('Voltage control' after telemetry): homing lost, "
                        'safe voltage written, disarmed; gripper/arm required',
    'homing_done': 'homing done',
    'homing_failed': 'homing failed',
}


class GripperDriverCore:
    """A `GripperBridge` wired to a `SerialLink`: what the lifecycle node wraps.

    Lifecycle mapping: configure → `configure` (opens the port; `LinkError` names it);
    activate → `activate` then `start_watchdog` (or a ≥ 100 Hz timer calling `watchdog`);
    deactivate → `deactivate` (safe voltage first); cleanup → `cleanup`; shutdown / process
    exit → `shutdown`.

    `start_watchdog` supervises the link from a thread of its own rather than an executor
    timer: it does not depend on (or add load to) the executor, so a starved or busy executor
    can neither delay link-loss detection nor, through the GIL, the 500 Hz reader.

    Args:
        port: Port path or pyserial URL.
        params: Bridge parameters.
        clock: Node clock [s]; stamps every line and event.
        baudrate: Baud rate [Bd].
        reconnect: Back-off parameters.
        on_result: Called on the reader thread after each line was handled and its command
            written (publish status/motor command here; must not block).
        on_event: ``(t, kind, message)`` for logging/diagnostics; kinds: ``'connected'``,
            ``'lost'``, ``'error'``, ``'firmware_restart'``, ``'homing_done'``,
            ``'homing_failed'``, ``'stale'``, ``'fault'``, ``'host_stall'`` (after a stall,
            nothing was done to the device), ``'host_stall_fault'`` (the loop stayed stuck for
            ``link.host_stall_limit`` while the watchdog ran: safe voltage, disarmed). The
            message says what the driver did.
        opener: Stream factory (tests inject fakes).
        read_timeout_s: Serial read timeout [s].
        thread_setup: Called first on the serial reader thread (`realtime.ThreadTuning.apply`).
    """

    def __init__(self, port: str, params: BridgeParams, *, clock: Clock,
                 baudrate: int = 115200, reconnect: ReconnectParams = ReconnectParams(),
                 on_result: LineResultCallback | None = None,
                 on_event: EventCallback | None = None,
                 opener: Callable[..., ByteStream] = open_stream,
                 read_timeout_s: float = 0.02,
                 thread_setup: Callable[[], object] | None = None) -> None:
        self._clock = clock
        self._on_result = on_result
        self._on_event = on_event
        self._thread_setup = thread_setup
        self._last_state = LinkState.INACTIVE
        self._watchdog_stop = threading.Event()
        self._watchdog_thread: threading.Thread | None = None
        self.watchdog_errors = 0  #: exceptions raised in a watchdog tick (a bug; reported)
        self._handled = float('nan')  # read stamp of the newest lines the bridge processed
        self.link = SerialLink(port, clock=clock, on_line=self._handle_line,
                               on_connected=self._handle_connected, on_lost=self._handle_lost,
                               on_error=self._handle_error, baudrate=baudrate,
                               read_timeout_s=read_timeout_s, reconnect=reconnect,
                               opener=opener, thread_setup=thread_setup,
                               on_chunk=self._handle_chunk)
        self.bridge = GripperBridge(params, writer=self.link.write)

    @property
    def port(self) -> str:
        """Port path or URL."""
        return self.link.url

    def configure(self) -> None:
        """Open the port and write the safe voltage.

        Raises:
            LinkError: The port cannot be opened (message names it).
        """
        self.link.open()

    def activate(self, t: float, open_retry: bool = False) -> None:
        """Arm and start the reader thread (the 500 Hz loop).

        Args:
            t: Activation time [s].
            open_retry: `configure` failed to open the port: the reader keeps opening it with
                back-off (``reconnect.*``, each failure an ``'error'`` event) until it
                succeeds or `deactivate` is called.

        Raises:
            LinkError: `configure` never succeeded and ``open_retry`` is False.
        """
        self.bridge.activate(t)
        try:
            self.link.start(open_retry=open_retry)
        except LinkError:
            self.bridge.deactivate(t)
            raise

    def watchdog(self, t: float) -> WatchdogResult:
        """Supervise the link at time ``t`` [s]; reconnects on a fault.

        Bytes waiting at the port (`SerialLink.input_pending`), or held by the kernel on
        their way there (`SerialLink.kernel_holds_input`), tell a host stall from a silent
        device.
        """
        result = self.bridge.check_watchdog(t, self._unprocessed,
                                            self.link.kernel_holds_input)
        if result.state != self._last_state and result.state == LinkState.STALE:
            self._emit(t, 'stale', f'{self.port}: {result.reason}; {self._stale_text(t, result)}')
        if result.state == LinkState.FAULT and result.reconnect:
            self._emit(t, 'fault', f'{self.port}: {result.reason}; link fault: safe voltage '
                       'written, disarmed (gripper/arm required), reconnecting')
        if result.state == LinkState.LAGGING and result.disarmed:
            where = self.link.reader_wait_channel() or 'running'
            self._emit(t, 'host_stall_fault', f'{self.port}: {result.reason} (reader thread in '
                       f'the kernel: {where}); safe voltage written, disarmed (gripper/arm '
                       'required)')
        self._last_state = result.state
        if result.reconnect:
            self.link.request_reconnect(result.reason)
        return result

    def _stale_text(self, t: float, result: WatchdogResult) -> str:
        """What a stale link did (``link.stale_action`` and the bridge's state)."""
        resume = 'the loop resumes with the next telemetry line'
        if result.held:
            fault = self.bridge.params.link.fault_after
            return (f'last command held by the firmware, still armed ({resume}; link fault '
                    f'after {fault:.3f} s)')
        if self.bridge.status(t).armed:
            return f'safe voltage written, still armed ({resume})'
        return 'safe voltage applied (not armed)'

    def start_watchdog(self, period_s: float, on_tick: WatchdogCallback | None = None) -> None:
        """Call `watchdog` every ``period_s`` [s] on a thread of its own until deactivation.

        The period is waited on the monotonic clock; each check uses ``clock()`` (the node
        clock), like a steady-clock timer would. ``on_tick(t, result)`` runs after each check
        on that thread (publish a degraded status there; must not block).
        """
        if self._watchdog_thread is not None and self._watchdog_thread.is_alive():
            return
        self._watchdog_stop.clear()
        self._watchdog_thread = threading.Thread(
            target=self._watchdog_loop, args=(period_s, on_tick),
            name=f'link-watchdog {self.port}', daemon=True)
        self._watchdog_thread.start()

    def stop_watchdog(self, timeout_s: float = 1.0) -> None:
        """Stop the watchdog thread (idempotent)."""
        self._watchdog_stop.set()
        thread = self._watchdog_thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout_s)
        self._watchdog_thread = None

    def deactivate(self, t: float) -> bool:
        """Write the safe voltage, then stop the reader and watchdog; True if written."""
        written = self.bridge.deactivate(t)
        self.link.stop()
        self.stop_watchdog()
        return written

    def cleanup(self, t: float) -> None:
        """Safe voltage (if still possible), stop and close the port."""
        self.bridge.deactivate(t)
        self.stop_watchdog()
        self.link.close()

    def shutdown(self, t: float) -> None:
        """Same as `cleanup`; safe to call more than once."""
        self.cleanup(t)

    def stats(self) -> LinkStats:
        """Link counters."""
        return self.link.stats()

    # ------------------------------------------------------------------ callbacks
    def _watchdog_loop(self, period_s: float, on_tick: WatchdogCallback | None) -> None:
        if self._thread_setup is not None:
            try:
                self._thread_setup()
            except Exception as exc:
                self._emit(self._clock(), 'error', f'{self.port}: watchdog thread setup: {exc}')
        stop = self._watchdog_stop
        while not stop.wait(period_s):
            t = self._clock()
            try:
                result = self.watchdog(t)
                if on_tick is not None:
                    on_tick(t, result)
            except Exception as exc:
                self.watchdog_errors += 1
                self._emit(t, 'error', f'{self.port}: watchdog tick raised '
                           f'{type(exc).__name__}: {exc}')

    def _unprocessed(self) -> int:
        """Data that arrived but was not processed yet: bytes waiting at the port, bytes the
        reader is taking off the port, or a read newer than the newest one the bridge handled
        (the reader holds it)."""
        link = self.link
        return link.input_pending() or int(link.read_in_progress
                                           or link.last_read_stamp > self._handled)

    def _emit(self, t: float, kind: str, message: str) -> None:
        if self._on_event is not None:
            self._on_event(t, kind, message)

    def _handle_line(self, line: bytes, overflow: bool, t: float) -> None:
        result = self.bridge.on_line(line, overflow, t)
        self._handled = t
        self._handle_result(result)

    def _handle_chunk(self, lines: list[tuple[bytes, bool]], t: float) -> None:
        results = self.bridge.on_lines(lines, t, TELEMETRY_PERIOD_S)
        self._handled = t
        for result in results:
            self._handle_result(result)

    def _handle_result(self, result: LineResult) -> None:
        if result.event:
            self._emit(result.stamp, result.event,
                       f'{self.port}: {self._event_text(result.event)}')
        if self._on_result is not None:
            self._on_result(result)

    def _event_text(self, event: str) -> str:
        if event == 'host_stall':
            d = self.bridge.diagnostics(self._clock())
            return (f'host stall: telemetry was processed {d.last_host_stall_s * 1e3:.0f} ms '
                    'late while the firmware kept sending; nothing was written meanwhile (the '
                    'last command stayed applied), not disarmed; the command resumes '
                    'rate-limited')
        if event == 'homing_failed':
            return f'homing failed: {self.bridge.homing.message}'
        return EVENT_TEXT.get(event, event.replace('_', ' '))

    def _handle_connected(self, t: float, port: str) -> None:
        self.bridge.on_connected(t, port)
        self._emit(t, 'connected', f'{port}: connected')

    def _handle_lost(self, t: float, reason: str) -> None:
        self.bridge.on_link_lost(t, reason)
        self._emit(t, 'lost', reason)

    def _handle_error(self, t: float, message: str) -> None:
        self._emit(t, 'error', message)
