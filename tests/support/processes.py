"""Processes by ROS domain, read from ``/proc`` (Linux): the root conftest's check that no test
module leaves a process running on the run's domain."""
from __future__ import annotations

import os
from pathlib import Path


def ancestors() -> set[int]:
    """This process and its ancestors (the shell of tools/run_ros.sh, make, CI)."""
    pids, pid = set(), os.getpid()
    while pid > 1 and pid not in pids:
        pids.add(pid)
        try:
            stat = Path(f'/proc/{pid}/stat').read_text()
        except OSError:
            break
        pid = int(stat.rsplit(')', 1)[1].split()[1])
    return pids


def processes_on_domain(domain: str) -> dict[int, str]:
    """Live ROS processes (not zombies, with the ROS client library loaded) whose environment
    has ``ROS_DOMAIN_ID=domain``: pid → command line. Helpers without ROS (multiprocessing's
    resource tracker, shells) cannot join the domain and are not listed."""
    found: dict[int, str] = {}
    needle = f'ROS_DOMAIN_ID={domain}'.encode()
    for entry in Path('/proc').iterdir():
        if not entry.name.isdigit():
            continue
        try:
            if needle not in (entry / 'environ').read_bytes().split(b'\0'):
                continue
            if (entry / 'stat').read_text().rsplit(')', 1)[1].split()[0] == 'Z':
                continue
            if not _loads_ros((entry / 'maps').read_text()):
                continue
            cmd = (entry / 'cmdline').read_bytes().replace(b'\0', b' ').decode(errors='replace')
        except OSError:
            continue
        found[int(entry.name)] = cmd.strip()
    return found


def _loads_ros(maps: str) -> bool:
    """The memory map (``/proc/PID/maps``) has the ROS client library in it."""
    return 'librcl.so' in maps or 'librmw' in maps
