"""A minimal RFC 6455 WebSocket client (stdlib only) for testing the Foxglove live server.

``websockets`` is not installed in the venv; the Foxglove WebSocket protocol needs only the
upgrade handshake with a subprotocol, masked client text frames and unmasked server frames.
"""
from __future__ import annotations

import base64
import json
import os
import socket
import struct
import time
from typing import Any


class WsClient:
    """Connects, negotiates ``subprotocol`` and exchanges frames (text → JSON, binary → bytes)."""

    def __init__(self, host: str, port: int, subprotocol: str = 'foxglove.sdk.v1',
                 timeout_s: float = 10.0) -> None:
        self.sock = socket.create_connection((host, port), timeout=timeout_s)
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall((f'GET / HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\n'
                           f'Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n'
                           f'Sec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: {subprotocol}'
                           '\r\n\r\n').encode())
        self._buf = b''
        while b'\r\n\r\n' not in self._buf:
            chunk = self.sock.recv(4096)
            if not chunk:
                raise ConnectionError('server closed during the handshake')
            self._buf += chunk
        head, self._buf = self._buf.split(b'\r\n\r\n', 1)
        self.response = head.decode(errors='replace')
        if not self.response.startswith('HTTP/1.1 101'):
            raise ConnectionError(f'handshake refused: {self.response.splitlines()[0]}')

    def _read(self, n: int) -> bytes:
        while len(self._buf) < n:
            chunk = self.sock.recv(65536)
            if not chunk:
                raise ConnectionError('connection closed')
            self._buf += chunk
        out, self._buf = self._buf[:n], self._buf[n:]
        return out

    def recv(self) -> tuple[int, bytes]:
        """Next complete frame: ``(opcode, payload)`` (fragments joined, pings answered)."""
        opcode, payload = 0, b''
        while True:
            b0, b1 = self._read(2)
            length = b1 & 0x7F
            if length == 126:
                length = struct.unpack('>H', self._read(2))[0]
            elif length == 127:
                length = struct.unpack('>Q', self._read(8))[0]
            mask = self._read(4) if b1 & 0x80 else b''
            data = self._read(length)
            if mask:
                data = bytes(c ^ mask[i % 4] for i, c in enumerate(data))
            op = b0 & 0x0F
            if op == 0x9:  # ping
                self._send(0xA, data)
                continue
            opcode = op or opcode
            payload += data
            if b0 & 0x80:
                return opcode, payload

    def _send(self, opcode: int, data: bytes) -> None:
        mask = os.urandom(4)
        head = bytes([0x80 | opcode])
        if len(data) < 126:
            head += bytes([0x80 | len(data)])
        elif len(data) < 65536:
            head += bytes([0x80 | 126]) + struct.pack('>H', len(data))
        else:
            head += bytes([0x80 | 127]) + struct.pack('>Q', len(data))
        self.sock.sendall(head + mask + bytes(c ^ mask[i % 4] for i, c in enumerate(data)))

    def send_json(self, value: Any) -> None:
        """Send a JSON text frame."""
        self._send(0x1, json.dumps(value).encode())

    def collect(self, until: Any, timeout_s: float) -> list[tuple[int, Any]]:
        """Frames (text decoded as JSON) until ``until(frames)`` is true or the time is up."""
        frames: list[tuple[int, Any]] = []
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline and not until(frames):
            self.sock.settimeout(max(0.05, deadline - time.monotonic()))
            try:
                opcode, data = self.recv()
            except TimeoutError:
                break
            frames.append((opcode, json.loads(data) if opcode == 0x1 else data))
        return frames

    def close(self) -> None:
        """Send a close frame (status 1000), then close the socket."""
        try:
            self._send(0x8, struct.pack('>H', 1000))
        except OSError:
            pass
        self.sock.close()
