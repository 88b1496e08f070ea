"""``slip_bag``: info, CSV export, record and replay of rosbag2 (MCAP) bags.

Examples::

    slip_bag info bags/linear_slip
    slip_bag export bags/linear_slip --out /tmp/csv --topic /gripper/status
    slip_bag record /tmp/my_bag --topic '/finger_*' --topic /gripper/status
    slip_bag replay bags/linear_slip --rate 2.0 --topic '/finger_*'
"""
from __future__ import annotations

import argparse
import sys

from slip_cell_common.bag_io import BagError, bag_info, export_csv


def _ros_args(pairs: list[tuple[str, str]]) -> list[str]:
    out = ['slip_bag', '--ros-args']
    for name, value in pairs:
        out += ['-p', f'{name}:={value}']
    return out


def _list(values: list[str] | None, default: str = "['*']") -> str:
    return default if not values else '[' + ','.join(f"'{v}'" for v in values) + ']'


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit code (2 with a clear message for bad bags)."""
    parser = argparse.ArgumentParser(prog='slip_bag', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest='command', required=True)
    p_info = sub.add_parser('info', help='print duration, message counts and types')
    p_info.add_argument('bag')
    p_exp = sub.add_parser('export', help='one CSV per topic')
    p_exp.add_argument('bag')
    p_exp.add_argument('--out', required=True)
    p_exp.add_argument('--topic', action='append', help='topic to export (repeatable)')
    p_rec = sub.add_parser('record', help='record topics until Ctrl-C')
    p_rec.add_argument('bag')
    p_rec.add_argument('--topic', action='append', help='glob pattern (repeatable); default all')
    p_rec.add_argument('--use-sim-time', action='store_true')
    p_rep = sub.add_parser('replay', help='publish a bag with its timing and /clock')
    p_rep.add_argument('bag')
    p_rep.add_argument('--rate', type=float, default=1.0, help='speed factor; 0 = max')
    p_rep.add_argument('--topic', action='append', help='glob pattern (repeatable); default all')
    p_rep.add_argument('--include-commands', action='store_true',
                       help='also publish command topics (can move hardware!)')
    p_rep.add_argument('--no-clock', action='store_true')
    p_rep.add_argument('--start-delay', type=float, default=2.0,
                       help='wait up to this long [s] for subscribers before playing')
    ns = parser.parse_args(argv)
    try:
        if ns.command == 'info':
            print(bag_info(ns.bag).format())
        elif ns.command == 'export':
            for path in export_csv(ns.bag, ns.out, ns.topic):
                print(path)
        elif ns.command == 'record':
            from slip_bringup.bag_nodes import recorder_main
            return recorder_main(_ros_args([('output', ns.bag), ('topics', _list(ns.topic)),
                                            ('use_sim_time', str(ns.use_sim_time).lower())]))
        elif ns.command == 'replay':
            from slip_bringup.bag_nodes import replay_main
            return replay_main(_ros_args([
                ('bag', ns.bag), ('rate', repr(float(ns.rate))), ('topics', _list(ns.topic)),
                ('include_commands', str(ns.include_commands).lower()),
                ('publish_clock', str(not ns.no_clock).lower()),
                ('start_delay', repr(float(ns.start_delay)))]))
    except BagError as exc:
        print(f'slip_bag: error: {exc}', file=sys.stderr)
        return 2
    return 0


if __name__ == '__main__':
    sys.exit(main())
