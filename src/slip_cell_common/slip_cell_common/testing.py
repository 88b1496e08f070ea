"""Test helpers shared by every package's tests (real rclpy, real DDS, bounded waits).

Never use ``rclpy.spin_until_future_complete`` in loops (rclpy 7.1.6 leaks executor tasks);
`spin_until` spins an executor until a predicate holds or a timeout passes.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any
from collections.abc import Callable, Sequence

from slip_cell_common.calls import call_service, spin_until  # noqa: F401 (re-export)
from slip_cell_common.executor_turn import spin_once_outliving_destruction


class SpinThread:
    """Spin an executor on a daemon thread (``spin_once`` slices) until `stop`.

    `stop` joins the thread, so no wait set still holds entities when the caller then shuts the
    executor down or destroys nodes. Also a context manager (starts on enter, stops on exit).

    Args:
        executor: Any rclpy executor with its nodes added.
        on_start: Called once on the spinning thread before it spins (e.g. thread tuning).
        slice_s: ``spin_once`` timeout [s]: the longest `stop` waits for the thread.
    """

    def __init__(self, executor: Any, on_start: Callable[[], Any] | None = None,
                 slice_s: float = 0.05) -> None:
        self.executor = executor
        self._on_start = on_start
        self._slice_s = slice_s
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name='spin', daemon=True)
        #: Turns lost to an entity destroyed while the executor collected them (see
        #: `slip_cell_common.executor_turn`).
        self.lost_turns = 0

    def start(self) -> SpinThread:
        """Start spinning; returns self."""
        self._thread.start()
        return self

    def _run(self) -> None:
        if self._on_start is not None:
            self._on_start()
        while not self._stop.is_set():
            if not spin_once_outliving_destruction(self.executor, self._slice_s):
                self.lost_turns += 1

    @property
    def alive(self) -> bool:
        """The thread still spins (an error raised by a turn ends it)."""
        return self._thread.is_alive()

    def stop(self, timeout_s: float = 2.0) -> None:
        """Stop spinning and join the thread (bounded by ``timeout_s``)."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout_s)

    def __enter__(self) -> SpinThread:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


def workspace_root() -> Path:
    """Repository root (the directory holding ``install/``), from the environment or this file."""
    env = os.environ.get('SLIP_WORKSPACE')
    if env:
        return Path(env)
    for parent in Path(__file__).resolve().parents:
        if (parent / 'install').is_dir() and (parent / 'src').is_dir():
            return parent
    raise RuntimeError('cannot locate the workspace root; set SLIP_WORKSPACE')


class NodeProcess:
    """A node (or any ROS program) in its own process, stopped with SIGINT then SIGKILL.

    Output goes to a log file so a failing test can show it (``output()``).
    """

    def __init__(self, argv: Sequence[str], log_path: Path, env: dict[str, str] | None = None,
                 cwd: Path | None = None) -> None:
        self.argv = list(argv)
        self.log_path = log_path
        self._log = open(log_path, 'wb')
        self.proc = subprocess.Popen(self.argv, stdout=self._log, stderr=subprocess.STDOUT,
                                     env=env if env is not None else os.environ.copy(),
                                     cwd=cwd, start_new_session=True)

    @classmethod
    def python_module(cls, module: str, args: Sequence[str], log_path: Path,
                      env: dict[str, str] | None = None) -> NodeProcess:
        """Run ``python -m module args`` with this interpreter."""
        return cls([sys.executable, '-m', module, *args], log_path, env)

    def running(self) -> bool:
        """True while the process has not exited."""
        return self.proc.poll() is None

    def stop(self, timeout_s: float = 8.0) -> int:
        """SIGINT, wait up to ``timeout_s``, then SIGKILL the process group; returns the exit
        code."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(timeout=timeout_s)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait(timeout=5.0)
        self._log.close()
        return self.proc.returncode

    def output(self) -> str:
        """Everything the process printed so far."""
        if not self._log.closed:
            self._log.flush()
        return self.log_path.read_text(errors='replace')
