# SPDX-License-Identifier: Apache-2.0
"""Latency tuning of the driver process: scheduling of the loop threads and the GC (ROS-free).

What made the 500 Hz loop miss ticks on a loaded 2-core machine (bench_gripper_loop):

* **Scheduling**: between the line's arrival and its command write the reader thread sat in
  the run queue for up to 2.3 ms while other processes (and the firmware emulator it had just
  woken by writing) ran. `ThreadTuning` gives the threads of the loop (serial reader, Net F/T
  readers) ``SCHED_FIFO`` or a lower niceness, when the process is permitted to; otherwise it
  fails soft and reports why. Linux schedules threads, so it is applied *inside* each thread
  (``pid 0`` = the calling thread).
* **GC pauses**: a full collection walks every tracked object of the process (rclpy, numpy and
  the message modules are tens of thousands); whichever thread allocates when it triggers
  pays for it while holding the GIL, so the reader waits too. `freeze_gc` moves everything
  alive after configure into the permanent generation (never scanned again) and raises the
  generation-0 threshold only if it was set below `GC_THRESHOLD_0`. Measured: young
  collections take 0.1–0.2 ms and stay short at the default threshold (a larger threshold
  makes each one scan more); what hurt were full collections (75 ms in the node process,
  and 400 collections in 5 s in a fat test process), which freezing removes.

Neither changes what the loop computes; they only change when it gets the CPU.

**Unfreeze before the process ends** (`unfreeze_gc`, called by the node's cleanup and
shutdown): CPython never collects the permanent generation, also not in its last collection
at interpreter exit. Frozen objects that live in reference cycles — rclpy's context, node and
entity handles among them — are then never destroyed, so the DDS participant is still alive,
with its threads running, when the C++ libraries' static destructors run at exit. Measured
with bench/bench_driver_start_stop.py: 7 of 300 driver shutdowns ended in
``malloc_consolidate(): unaligned fastbin chunk detected`` (exit −6) or a segfault with
``realtime.freeze_gc`` true, none of 150 with it false (issue 16 item 8).
"""
from __future__ import annotations

import gc
import os
import threading
from dataclasses import dataclass, field

from slip_cell_common.core.validation import validate_fields

#: Lowest generation-0 threshold `freeze_gc` leaves (CPython default 700: net allocations
#: between collections stay small, so each young collection stays short).
GC_THRESHOLD_0 = 700


@dataclass(frozen=True)
class RealtimeParams:
    """Scheduling of the loop threads and GC tuning (parameter group ``realtime``)."""

    priority: int = field(default=10, metadata={
        'range': (0, 99), 'read_only': True,
        'description': 'SCHED_FIFO priority of the serial and Net F/T reader threads; 0 = '
                       'normal scheduling. Needs CAP_SYS_NICE or an rtprio limit; without '
                       'them a warning is logged and the threads run normally'})
    nice: int = field(default=0, metadata={
        'range': (-20, 19), 'read_only': True,
        'description': 'niceness of those threads when SCHED_FIFO is off or not permitted; '
                       '0 = unchanged (negative values need CAP_SYS_NICE or RLIMIT_NICE)'})
    freeze_gc: bool = field(default=True, metadata={
        'read_only': True,
        'description': 'after configure: collect once, then freeze the surviving objects so '
                       'later collections never scan them (no long GC pauses in the loop)'})

    def validate(self) -> None:
        """Raise `ParameterError` listing every invalid field."""
        validate_fields(self)


class ThreadTuning:
    """Applies `RealtimeParams` scheduling to the calling thread; thread-safe, never raises.

    Pass `apply` as the ``thread_setup`` hook of `transport.SerialLink` and
    `netft_client.NetFTClient`; read `results` (thread name → outcome) for logs and diagnostics.

    Args:
        priority: ``SCHED_FIFO`` priority (1–99); 0 = leave the policy alone.
        nice: Niceness used when ``priority`` is 0 or not permitted; 0 = unchanged.
    """

    def __init__(self, priority: int = 0, nice: int = 0) -> None:
        self.priority = priority
        self.nice = nice
        self._lock = threading.Lock()
        self._results: dict[str, str] = {}
        self._failures: list[str] = []

    @classmethod
    def from_params(cls, params: RealtimeParams) -> ThreadTuning:
        """The tuning a parameter set asks for."""
        return cls(params.priority, params.nice)

    @property
    def results(self) -> dict[str, str]:
        """Outcome per thread name (``'SCHED_FIFO 10'``, ``'nice -5'``, ``'normal'`` or why)."""
        with self._lock:
            return dict(self._results)

    def take_failures(self) -> list[str]:
        """Failure messages since the last call (for logging once, outside the threads)."""
        with self._lock:
            out, self._failures = self._failures, []
            return out

    def apply(self) -> bool:
        """Tune the calling thread; True when everything asked for took effect.

        ``SCHED_FIFO`` is tried first; the niceness only when FIFO is off or was refused.
        """
        name = threading.current_thread().name
        outcome = 'normal'
        problems: list[str] = []
        attempts = ((self.priority > 0, set_fifo_priority, self.priority, 'SCHED_FIFO'),
                    (self.nice != 0, set_niceness, self.nice, 'nice'))
        for wanted, setter, value, label in attempts:
            if not wanted or outcome != 'normal':
                continue
            message = setter(value)
            if message:
                problems.append(message)
            else:
                outcome = f'{label} {value}'
        if problems:
            outcome = f'{outcome} ({"; ".join(problems)})'
        with self._lock:
            self._results[name] = outcome
            self._failures.extend(f'{name}: {p}' for p in problems)
        return not problems


def set_fifo_priority(priority: int) -> str:
    """Put the calling thread under ``SCHED_FIFO`` at ``priority``; '' or why it failed."""
    setter = getattr(os, 'sched_setscheduler', None)
    if setter is None:
        return 'SCHED_FIFO is not available on this platform'
    try:
        low = os.sched_get_priority_min(os.SCHED_FIFO)
        high = os.sched_get_priority_max(os.SCHED_FIFO)
        setter(0, os.SCHED_FIFO, os.sched_param(min(max(priority, low), high)))
    except PermissionError:
        return (f'SCHED_FIFO priority {priority} not permitted (needs CAP_SYS_NICE or '
                f'an rtprio limit, e.g. "ulimit -r {priority}" via limits.conf)')
    except OSError as exc:
        return f'SCHED_FIFO priority {priority} failed: {exc}'
    return ''


def set_niceness(nice: int) -> str:
    """Set the calling thread's niceness (Linux: per thread); '' or why it failed."""
    try:
        os.setpriority(os.PRIO_PROCESS, 0, nice)
    except PermissionError:
        return f'niceness {nice} not permitted (needs CAP_SYS_NICE or RLIMIT_NICE)'
    except (OSError, AttributeError) as exc:
        return f'niceness {nice} failed: {exc}'
    return ''


def freeze_gc(threshold_0: int = GC_THRESHOLD_0) -> int:
    """Collect, freeze every surviving object, keep the generation-0 threshold ≥ ``threshold_0``.

    Call once set-up has allocated what it keeps (after configure). Idempotent in effect:
    later calls freeze what was created since.

    Args:
        threshold_0: New generation-0 threshold (net allocations of tracked objects).

    Returns:
        Objects in the permanent generation afterwards.
    """
    gc.collect()
    gc.freeze()
    _, t1, t2 = gc.get_threshold()
    if gc.get_threshold()[0] < threshold_0:
        gc.set_threshold(threshold_0, t1, t2)
    return gc.get_freeze_count()


def unfreeze_gc() -> int:
    """Undo `freeze_gc`: the frozen objects become collectable again (see the module
    docstring: at exit they must be, so that rclpy and DDS are torn down before the C++ static
    destructors run). Call at cleanup/shutdown, after the loop threads have stopped.

    Returns:
        Objects that were frozen.
    """
    frozen = gc.get_freeze_count()
    gc.unfreeze()
    return frozen
