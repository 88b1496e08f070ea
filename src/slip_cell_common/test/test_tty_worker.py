# SPDX-License-Identifier: Apache-2.0
"""`SerialLink.kernel_holds_input` on the real kernel: while the kernel's tty worker cannot
run (real-time CPU burners on every CPU, about one second), a real-time reader of a pty whose
device side keeps writing waits for it, and the link says so; with the worker free it does
not. Needs Linux and permission for SCHED_FIFO (skipped otherwise)."""
from __future__ import annotations

import os
import subprocess
import sys
import threading
import time

import pytest

from slip_cell_common.core.serial_transport import SerialLink
from slip_cell_common.core.tty_worker import waiting_for_tty_worker

BURN_S = 1.2


def _fifo(priority: int) -> None:
    os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))


def _can_use_fifo() -> bool:
    if not sys.platform.startswith('linux'):
        return False
    try:
        before = os.sched_getscheduler(0), os.sched_getparam(0)
        _fifo(1)
        os.sched_setscheduler(0, before[0], before[1])
    except (OSError, AttributeError):
        return False
    return True


def test_no_thread_or_a_gone_thread_is_not_waiting() -> None:
    assert not waiting_for_tty_worker(None)
    assert not waiting_for_tty_worker(2 ** 31 - 7)       # no such thread in this process
    assert not waiting_for_tty_worker(threading.get_native_id())  # running, not waiting


@pytest.mark.slow
@pytest.mark.skipif(not _can_use_fifo(), reason='needs Linux and SCHED_FIFO permission')
def test_a_reader_starved_of_the_tty_worker_is_seen_waiting_for_the_kernel(pty) -> None:
    master, path = pty
    lines = [0]
    link = SerialLink(path, clock=time.monotonic, on_line=lambda *a: lines.__setitem__(
        0, lines[0] + 1), thread_setup=lambda: _fifo(50))
    link.open()
    link.start()
    stop = threading.Event()

    def device() -> None:                        # the firmware: a line every 2 ms
        _fifo(55)
        while not stop.is_set():
            os.write(master, b'0.1234\r\n')
            time.sleep(0.002)

    writer = threading.Thread(target=device, daemon=True)
    writer.start()
    old = os.sched_getscheduler(0), os.sched_getparam(0)
    free: list[bool] = []
    starved: list[bool] = []
    burners: list[subprocess.Popen[bytes]] = []
    try:
        _fifo(60)                                # this thread samples above everything
        deadline = time.monotonic() + 0.5
        while time.monotonic() < deadline:
            free.append(link.kernel_holds_input())
            time.sleep(0.005)
        burn = ('import os, time\n'
                'os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(10))\n'
                f't = time.monotonic()\nwhile time.monotonic() - t < {BURN_S}: pass')
        burners = [subprocess.Popen([sys.executable, '-c', burn])
                   for _ in range(os.cpu_count() or 1)]
        time.sleep(0.1)
        deadline = time.monotonic() + BURN_S - 0.3
        while time.monotonic() < deadline:
            starved.append(link.kernel_holds_input())
            time.sleep(0.005)
    finally:
        os.sched_setscheduler(0, old[0], old[1])
        for burner in burners:
            burner.wait(10.0)
        stop.set()
        writer.join(2.0)
        link.close()
    assert lines[0] > 100                        # the reader did read the device
    assert sum(free) <= 0.1 * len(free), (sum(free), len(free))
    assert sum(starved) >= 0.3 * len(starved), (sum(starved), len(starved))
