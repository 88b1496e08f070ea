# SPDX-License-Identifier: Apache-2.0
"""Matching sensors to fingers by their ``n`` reply, and catching two boards with one name.

Sensors are identified by the name compiled into their firmware (``sensor_1``, ``sensor_2``),
never by USB description or enumeration order (requirement HW-8). Two failure modes are
caught here:

* `assign_ports`: one process identified several ports and two of them answered the same name
  (both boards flashed as ``sensor_1``): `DuplicateSensorNameError` naming both ports.
* `NameClaim`: one driver process per sensor (HW-13). Each process claims its sensor name with
  an advisory file lock after the handshake; a second process whose port answers the same name
  cannot claim it and gets `DuplicateSensorNameError` naming the port that holds the claim.
"""
from __future__ import annotations

import errno
import fcntl
import os
import re
import tempfile
from pathlib import Path
from collections.abc import Mapping, Sequence

_SAFE = re.compile(r'[^A-Za-z0-9_.\-]')


class DuplicateSensorNameError(RuntimeError):
    """Two ports answered the same sensor name.

    Attributes:
        name: The contested name.
        ports: The ports that answered it (the holder first for `NameClaim`).
    """

    def __init__(self, name: str, ports: Sequence[str], detail: str = '') -> None:
        listed = ', '.join(p or '<unknown port>' for p in ports)
        suffix = f' {detail}' if detail else ''
        super().__init__(f'sensor name {name!r} answered by more than one port ({listed}); '
                         f'two boards flashed with the same name?{suffix}')
        self.name = name
        self.ports = tuple(ports)


class MissingSensorError(RuntimeError):
    """An expected sensor name was not answered by any port."""


def assign_ports(answers: Mapping[str, str | None],
                 expected_names: Sequence[str] = ()) -> dict[str, str]:
    """Map sensor names to ports from the per-port ``n`` replies.

    Args:
        answers: ``{port: answered name or None when the port did not answer}``.
        expected_names: Names that must be present (e.g. ``('sensor_1', 'sensor_2')``).

    Returns:
        ``{name: port}`` for every port that answered.

    Raises:
        DuplicateSensorNameError: Two ports answered the same name.
        MissingSensorError: An expected name was not answered (lists the silent ports).
    """
    by_name: dict[str, list[str]] = {}
    for port, name in answers.items():
        if name:
            by_name.setdefault(name, []).append(port)
    for name, ports in by_name.items():
        if len(ports) > 1:
            raise DuplicateSensorNameError(name, sorted(ports))
    missing = [n for n in expected_names if n not in by_name]
    if missing:
        silent = sorted(p for p, n in answers.items() if not n)
        raise MissingSensorError(f'no port answered {missing}; ports without an answer: {silent}')
    return {name: ports[0] for name, ports in by_name.items()}


def default_lock_dir() -> Path:
    """``$XDG_RUNTIME_DIR`` when set, else the system temporary directory."""
    runtime = os.environ.get('XDG_RUNTIME_DIR', '')
    return Path(runtime) if runtime and Path(runtime).is_dir() else Path(tempfile.gettempdir())


class NameClaim:
    """Host-wide claim of a sensor name by one port (advisory ``flock``; released on exit).

    Args:
        name: Sensor name to claim.
        port: Port that answered the name (stored in the lock file for error messages).
        lock_dir: Directory of the lock files (same for every driver process on the host).
    """

    def __init__(self, name: str, port: str, lock_dir: str | Path) -> None:
        self.name = name
        self.port = port
        self.path = Path(lock_dir) / f'slip_velocity_sensor.{_SAFE.sub("_", name)}.lock'
        self._fd: int | None = None

    @property
    def held(self) -> bool:
        """True while this object holds the claim."""
        return self._fd is not None

    def acquire(self) -> None:
        """Claim the name.

        Raises:
            DuplicateSensorNameError: Another holder (process or object) has the name.
            OSError: The lock file cannot be created.
        """
        if self._fd is not None:
            return
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            holder = os.read(fd, 4096).decode('utf-8', 'replace').strip()
            os.close(fd)
            if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise DuplicateSensorNameError(
                    self.name, [holder or '<unknown port>', self.port],
                    f'(claimed first by {holder or "another process"})') from exc
            raise
        os.ftruncate(fd, 0)
        os.write(fd, f'{self.port} pid={os.getpid()}\n'.encode())
        self._fd = fd

    def release(self) -> None:
        """Give the name up (idempotent)."""
        if self._fd is None:
            return
        fd, self._fd = self._fd, None
        try:
            os.ftruncate(fd, 0)
            fcntl.flock(fd, fcntl.LOCK_UN)
        finally:
            os.close(fd)

    def __enter__(self) -> NameClaim:
        self.acquire()
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()
