# SPDX-License-Identifier: Apache-2.0
"""ATI Net F/T Raw Data Transfer (RDT) datagrams: requests and records (ROS-free).

Protocol (hardware_protocols §4), big-endian:

* Request, host → box port 49152, 8 bytes ``'>HHI'``: header 0x1234, command, sample count
  (0 = until stopped). Commands: 0x0000 stop, 0x0002 start real-time streaming, 0x0003 start
  buffered streaming, 0x0041 reset the threshold latch, 0x0042 set the software bias (inside
  the box, for every client).
* Record, box → host, 36 bytes ``'>IIIiiiiii'``: rdt_sequence, ft_sequence, status, then
  Fx, Fy, Fz, Tx, Ty, Tz in counts. A datagram holds one record (real-time) or several
  (buffered); any size that is not a positive multiple of 36 is rejected.
"""
from __future__ import annotations

import struct
from enum import IntEnum
from typing import NamedTuple
from collections.abc import Sequence

RDT_PORT = 49152
REQUEST_HEADER = 0x1234
REQUEST = struct.Struct('>HHI')
RECORD = struct.Struct('>IIIiiiiii')
RECORD_SIZE = RECORD.size  # 36
_SEQ_MOD = 1 << 32


class RdtCommand(IntEnum):
    """RDT request commands."""

    STOP = 0x0000
    START_REALTIME = 0x0002
    START_BUFFERED = 0x0003
    RESET_LATCH = 0x0041
    SET_BIAS = 0x0042


class DatagramError(ValueError):
    """A datagram that is not a whole number of RDT records."""


def encode_request(command: int, sample_count: int = 0) -> bytes:
    """8-byte RDT request.

    Args:
        command: `RdtCommand` value.
        sample_count: Records to send (0 = until stopped), < 2³².
    """
    return REQUEST.pack(REQUEST_HEADER, int(command), sample_count)


def decode_request(data: bytes) -> tuple[int, int]:
    """``(command, sample_count)`` of a request (the emulator's side).

    Raises:
        DatagramError: Wrong size or header.
    """
    if len(data) != REQUEST.size:
        raise DatagramError(f'request of {len(data)} bytes, expected {REQUEST.size}')
    header, command, count = REQUEST.unpack(data)
    if header != REQUEST_HEADER:
        raise DatagramError(f'request header 0x{header:04X}, expected 0x{REQUEST_HEADER:04X}')
    return command, count


class RdtRecord(NamedTuple):
    """One RDT record as received (counts).

    Attributes:
        rdt_sequence: Record counter (loss/reorder detection).
        ft_sequence: Device measurement counter (stall/restart detection).
        status: Status word (`decode_status`).
        counts: (Fx, Fy, Fz, Tx, Ty, Tz) [counts].
    """

    rdt_sequence: int
    ft_sequence: int
    status: int
    counts: tuple[int, int, int, int, int, int]


def encode_record(rdt_sequence: int, ft_sequence: int, status: int,
                  counts: Sequence[int]) -> bytes:
    """36-byte record; sequences and status are reduced modulo 2³²."""
    c = [int(v) for v in counts]
    if len(c) != 6:
        raise ValueError(f'need 6 counts, got {len(c)}')
    return RECORD.pack(rdt_sequence % _SEQ_MOD, ft_sequence % _SEQ_MOD, status % _SEQ_MOD, *c)


def decode_datagram(data: bytes) -> list[RdtRecord]:
    """Records of one datagram.

    Raises:
        DatagramError: Empty or not a multiple of 36 bytes (truncated or foreign datagram).
    """
    n = len(data)
    if n == 0 or n % RECORD_SIZE:
        raise DatagramError(f'datagram of {n} bytes is not a multiple of {RECORD_SIZE}')
    return [RdtRecord(v[0], v[1], v[2], (v[3], v[4], v[5], v[6], v[7], v[8]))
            for v in RECORD.iter_unpack(data)]

