# SPDX-License-Identifier: Apache-2.0
"""Start/stop loop of the INSTALLED ``gripper_driver`` process (issue 16 item 8). Prints; never
asserts.

One run of the issue's report ended a driver shutdown with ``malloc_consolidate(): unaligned
fastbin chunk detected`` (exit −6). This script repeats what a user does: start the driver
against the firmware emulator (a child process serving the gripper pty and, unless
``--no-ft``, two Net F/T boxes the driver streams from), let it run for a random while
(0.2–1.5 s after it reports "active", optionally with a grasp command applied through its own
``gripper/arm``-free path: the emulator holds an object), then SIGINT, and wait for the exit.

Every cycle's exit code is recorded; any non-zero code, a signal, or a log mentioning
``malloc``, ``corrupted``, ``Aborted``, ``Segmentation`` or a traceback counts as a failure and
its log tail is printed. The driver runs with ``PYTHONFAULTHANDLER=1``, so a fatal signal
while Python runs prints the Python stack of every thread; the crash of issue 16 item 8 came
later, in the C++ exit handlers (``DomainParticipantFactory`` deleting a participant whose
threads still ran), where only a core file shows it: ``--core-dumps`` then
``gdb python <log folder>/cores/core -batch -ex 'thread apply all bt'``.

Run through ``tools/run_ros.sh``::

    tools/run_ros.sh .venv/bin/python bench/bench_driver_start_stop.py --cycles 300
"""
from __future__ import annotations

import argparse
import collections
import os
import random
import resource
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

_ROOT = Path(__file__).resolve().parents[1]
_EXE = _ROOT / 'install' / 'slip_gripper_driver' / 'lib' / 'slip_gripper_driver' / 'gripper_driver'
_CONFIG = _ROOT / 'src' / 'slip_gripper_driver' / 'config'
_BAD_WORDS = ('malloc', 'corrupted', 'Aborted', 'Segmentation', 'Traceback', 'double free')


def _free_udp_port(host: str) -> int:
    import socket
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind((host, 0))
        return probe.getsockname()[1]


def _start_emulator(link: str, boxes: list[str]) -> subprocess.Popen:
    cmd = [sys.executable, '-m', 'slip_gripper_driver.core.firmware_emulator', '--link', link,
           '--object-width', '0.03', '--initial-opening', '0.031']
    for box in boxes:
        cmd += ['--netft', box]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    deadline = time.monotonic() + 20.0
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if line.startswith('gripper firmware emulator on'):
            return proc
        if not line:
            break
    proc.kill()
    raise RuntimeError('firmware emulator did not start')


def _allow_core() -> None:
    resource.setrlimit(resource.RLIMIT_CORE, (resource.RLIM_INFINITY, resource.RLIM_INFINITY))


def _wait_for_text(path: Path, text: str, proc: subprocess.Popen, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if text in path.read_text(errors='replace'):
            return True
        if proc.poll() is not None:
            return False
        time.sleep(0.02)
    return False


def main() -> int:
    """Parse arguments, run the cycles, print the summary."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--cycles', type=int, default=300, help='start/stop cycles (default 300)')
    parser.add_argument('--no-ft', action='store_true',
                        help='ft.mode topic (no Net F/T streams in the driver process)')
    parser.add_argument('--seed', type=int, default=1, help='seed of the random run times')
    parser.add_argument('--max-run', type=float, default=1.5,
                        help='longest run after activation [s] (default 1.5)')
    parser.add_argument('--core-dumps', action='store_true',
                        help='let crashing drivers write a core file into the log folder '
                             '(for gdb: thread apply all bt)')
    parser.add_argument('--no-freeze-gc', action='store_true',
                        help='realtime.freeze_gc false in the driver (default: the shipped true)')
    args = parser.parse_args()
    if not _EXE.is_file():
        print(f'{_EXE} missing: run make setup', file=sys.stderr)
        return 2
    rng = random.Random(args.seed)
    tmp = Path(tempfile.mkdtemp(prefix='bench_start_stop_'))
    link = str(tmp / 'gripper')
    hosts = ('127.0.0.6', '127.0.0.5')
    box_port = _free_udp_port(hosts[0])
    boxes = [] if args.no_ft else [f'{h}:{box_port}' for h in hosts]
    emulator = _start_emulator(link, boxes)
    (tmp / 'cores').mkdir()
    site = tmp / 'site.yaml'
    ft = ("    ft: {mode: 'topic'}\n" if args.no_ft else
          f"    ft: {{mode: 'embedded', port: {box_port}, read_config: false, "
          f"counts_per_force: 1000000.0, counts_per_torque: 1000000.0, "
          f"finger_1: {{address: '{hosts[0]}'}}, finger_2: {{address: '{hosts[1]}'}}}}\n")
    site.write_text('gripper_driver:\n  ros__parameters:\n'
                    f"    serial: {{port: '{link}'}}\n" + ft
                    + ('    realtime: {freeze_gc: false}\n' if args.no_freeze_gc else ''))
    argv = [str(_EXE), '--ros-args', '--params-file', str(_CONFIG / 'cell.yaml'),
            '--params-file', str(_CONFIG / 'gripper_driver.yaml'), '--params-file', str(site)]
    env = dict(os.environ, PYTHONFAULTHANDLER='1')
    codes: collections.Counter[int] = collections.Counter()
    failures: list[tuple[int, int, str]] = []
    not_active = 0
    t0 = time.monotonic()
    try:
        for cycle in range(1, args.cycles + 1):
            log = tmp / f'driver_{cycle}.log'
            with open(log, 'wb') as out:
                proc = subprocess.Popen(argv, stdout=out, stderr=subprocess.STDOUT,
                                        start_new_session=True, env=env, cwd=tmp / 'cores',
                                        preexec_fn=_allow_core if args.core_dumps else None)
                if not _wait_for_text(log, 'active: armed', proc, 20.0):
                    not_active += 1
                time.sleep(rng.uniform(0.2, args.max_run))
                if proc.poll() is None:
                    proc.send_signal(signal.SIGINT)
                try:
                    code = proc.wait(timeout=15.0)
                except subprocess.TimeoutExpired:
                    os.killpg(proc.pid, signal.SIGKILL)
                    code = proc.wait(timeout=5.0)
                    code = code if code != 0 else -9
            text = log.read_text(errors='replace')
            codes[code] += 1
            bad = [w for w in _BAD_WORDS if w in text]
            if code != 0 or bad:
                failures.append((cycle, code, text[-4000:]))
            else:
                log.unlink()
            if cycle % 25 == 0:
                print(f'  {cycle} cycles, {len(failures)} failed, '
                      f'{time.monotonic() - t0:.0f} s', flush=True)
    finally:
        emulator.send_signal(signal.SIGINT)
        try:
            emulator.wait(timeout=10.0)
        except subprocess.TimeoutExpired:
            emulator.kill()
    print(f'gripper_driver start/stop: {args.cycles} cycles '
          f'({"no F/T" if args.no_ft else "2 embedded Net F/T streams"}, realtime.freeze_gc '
          f'{str(not args.no_freeze_gc).lower()}), {time.monotonic() - t0:.0f} s')
    print(f'  exit codes        {dict(sorted(codes.items()))}')
    print(f'  failed cycles     {len(failures)}   (not active within 20 s: {not_active})')
    for cycle, code, tail in failures[:5]:
        print(f'--- cycle {cycle}: exit {code}; log tail:\n{tail}')
    print(f'  logs of failed cycles in {tmp}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
