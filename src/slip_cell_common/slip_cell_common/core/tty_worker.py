# SPDX-License-Identifier: Apache-2.0
"""Is a thread waiting for the kernel's tty worker? (Linux, ``/proc``.)

Bytes a serial device sends (a USB CDC-ACM port, and a pseudo-terminal alike) first land in
the tty's flip buffer; a kernel worker thread of *normal* priority then moves them to the
line discipline, where ``read`` and ``poll`` find them. A reader that finds the line
discipline empty first waits for that work to finish (``tty_buffer_flush_work``). On a host
whose CPUs are busy that worker can wait for a CPU for a second or more (measured beside two
CPU-burning processes: 1.36 s), and a real-time reader waits with it: the device is sending,
the process cannot see it.

`waiting_for_tty_worker` tells that case from a silent device: the reader thread's kernel
wait channel is then ``__flush_work`` (a reader of a silent port sleeps in its poll
instead). Elsewhere (no ``/proc``), the answer is always False.
"""
from __future__ import annotations

#: Kernel wait channels of a thread that waits for a work item to finish.
FLUSH_WAIT_CHANNELS = frozenset({'__flush_work', 'flush_work', '__flush_work.isra.0'})


def wait_channel(native_thread_id: int | None) -> str:
    """The kernel function the thread (of this process) sleeps in, '' when it runs, is gone
    or the platform cannot tell."""
    if native_thread_id is None:
        return ''
    try:
        with open(f'/proc/self/task/{native_thread_id}/wchan') as wchan:
            channel = wchan.read().strip()
    except OSError:
        return ''
    return '' if channel == '0' else channel


def waiting_for_tty_worker(native_thread_id: int | None) -> bool:
    """True while the thread (``threading.get_native_id()`` of a thread of this process)
    waits for the kernel to flush pending received bytes; False when it does not, is gone,
    or the platform cannot tell."""
    return wait_channel(native_thread_id) in FLUSH_WAIT_CHANNELS
