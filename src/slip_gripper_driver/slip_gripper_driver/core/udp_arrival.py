# SPDX-License-Identifier: Apache-2.0
"""When a UDP datagram reached the host, as the kernel stamped it (ROS-free).

A reader thread that the scheduler held up finds several datagrams queued in its socket.
Stamped with the time it reads them, they would all look fresh although the oldest waited
tens of milliseconds. With ``SO_TIMESTAMPNS`` the kernel records each datagram's arrival;
`receive` returns the datagram with its age at the moment it was read, so the reader can stamp
it ``clock() − age`` on whatever clock it uses (the node clock, sim time, a test clock).

The kernel switches arrival stamping on for the host with a deferred work item, so the first
datagrams after the first `enable` on a host may carry the read time instead (an age near 0:
the old behaviour, never an age too large). The kernel stamp is on ``CLOCK_REALTIME``; only
a difference of two readings of that clock is used (an age), never a time of day. An age that
is negative or longer than `MAX_AGE_S` (the wall clock was stepped between arrival and read)
counts as unknown.

Python's `socket` module does not name ``SO_TIMESTAMPNS``; its value is the Linux generic one
(also ``SCM_TIMESTAMPNS``), used only on the architectures that share it. Elsewhere, or when
the kernel refuses the option, `enable` returns False and ages are unknown (the caller stamps
at read time, as before).
"""
from __future__ import annotations

import platform
import socket
import struct
import sys
from collections.abc import Callable

#: ``SO_TIMESTAMPNS`` / ``SCM_TIMESTAMPNS`` of Linux's generic socket options.
SO_TIMESTAMPNS = 35

#: Machines whose Linux ABI uses the generic socket option numbers.
_GENERIC_ABI = ('x86_64', 'aarch64', 'arm64', 'i386', 'i486', 'i586', 'i686', 'riscv64',
                'armv7l', 'armv8l', 'ppc64le', 's390x', 'loongarch64')

#: Longest plausible wait of a datagram in the socket [s]; longer means the clock was stepped.
MAX_AGE_S = 1.0

_TIMESPEC = struct.Struct('@qq')
_ANCILLARY_SIZE = socket.CMSG_SPACE(_TIMESPEC.size) if hasattr(socket, 'CMSG_SPACE') else 0


def supported() -> bool:
    """The platform can stamp datagram arrivals (Linux on a generic-ABI machine)."""
    return sys.platform.startswith('linux') and platform.machine() in _GENERIC_ABI \
        and _ANCILLARY_SIZE > 0


def enable(sock: socket.socket) -> bool:
    """Ask the kernel to stamp every datagram ``sock`` receives; True if it agreed."""
    if not supported():
        return False
    try:
        sock.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPNS, 1)
    except OSError:
        return False
    return True


def receive(sock: socket.socket, bufsize: int,
            wall_clock: Callable[[], float]) -> tuple[bytes, float | None]:
    """Read one datagram from a socket set up with `enable`.

    Args:
        sock: Non-blocking UDP socket.
        bufsize: Largest datagram to read [bytes].
        wall_clock: ``time.time`` (``CLOCK_REALTIME``, the kernel stamp's clock) [s].

    Returns:
        ``(data, age)``: how long [s] the datagram waited in the socket before this read, or
        None when the kernel gave no stamp or it is implausible.

    Raises:
        BlockingIOError: Nothing is queued. Other `OSError` as from ``recv``.
    """
    data, ancillary, _flags, _address = sock.recvmsg(bufsize, _ANCILLARY_SIZE)
    now = wall_clock()
    for level, kind, payload in ancillary:
        if level == socket.SOL_SOCKET and kind == SO_TIMESTAMPNS and \
                len(payload) >= _TIMESPEC.size:
            seconds, nanoseconds = _TIMESPEC.unpack_from(payload)
            age = now - (seconds + 1e-9 * nanoseconds)
            return data, age if 0.0 <= age <= MAX_AGE_S else None
    return data, None
