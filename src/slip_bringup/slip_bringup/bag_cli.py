"""``slip_bag``: info, CSV export, record and replay of rosbag2 (MCAP) bags.

Examples::

    slip_bag info bags/linear_slip
    slip_bag export bags/linear_slip --out /tmp/csv --topic /gripper/status
    slip_bag record /tmp/my_bag --topic '/finger_*' --topic /gripper/status
    slip_bag replay bags/linear_slip --rate 2.0 --topic '/finger_*'

Where bags go: ``record`` writes exactly the folder you name. The experiment runner and
``slip_demo`` default to ``$SLIP_DATA_DIR/bags`` (``$SLIP_DATA_DIR/demo/<time>``), else
``~/.local/share/slip_cell/...``, never into the working directory or the source tree.

Bags are checked before use: a missing, empty or foreign folder, a folder without
``metadata.yaml``, a truncated or corrupt MCAP file (chunk CRC), ``metadata.yaml`` counts that
disagree with the data, or a bag without messages end with one error line and exit code 2.
"""
from __future__ import annotations

import sys

from slip_cell_common.bag_io import BagError, bag_info, export_csv, validate_bag
from slip_cell_common.core.cli_args import Parser, non_negative_float, plain_doc


def _ros_args(pairs: list[tuple[str, str]]) -> list[str]:
    out = ['slip_bag', '--ros-args']
    for name, value in pairs:
        out += ['-p', f'{name}:={value}']
    return out


def _list(values: list[str] | None, default: str = "['*']") -> str:
    return default if not values else '[' + ','.join(f"'{v}'" for v in values) + ']'


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit code: 2 with a one-line message for a missing, foreign,
    damaged or empty bag."""
    parser = Parser(prog='slip_bag', description=plain_doc(__doc__))
    sub = parser.add_subparsers(dest='command', metavar='COMMAND', required=True,
                                help='what to do with the bag (COMMAND --help for its options)')
    bag_help = 'bag folder (rosbag2 with metadata.yaml and MCAP data)'
    p_info = sub.add_parser('info', help='print duration, message counts and types',
                            description='Duration, message count, type and QoS of every topic '
                                        '(a full pass over the data: CRCs and counts checked).')
    p_info.add_argument('bag', help=bag_help)
    p_exp = sub.add_parser('export', help='one CSV per topic',
                           description='Write one CSV file per topic (flattened message '
                                       'fields, header stamps in seconds).')
    p_exp.add_argument('bag', help=bag_help)
    p_exp.add_argument('--out', required=True, metavar='DIR',
                       help='directory for the CSV files (created; required)')
    p_exp.add_argument('--topic', action='append', metavar='TOPIC',
                       help='topic to export, repeatable (default: every topic)')
    p_rec = sub.add_parser('record', help='record topics until Ctrl-C',
                           description='Record topics to a new bag until Ctrl-C (a ROS node; '
                                       'run it on the graph\'s domain).')
    p_rec.add_argument('bag', help='bag folder to create (must not exist)')
    p_rec.add_argument('--topic', action='append', metavar='PATTERN',
                       help="topic glob pattern, repeatable, e.g. '/finger_*' "
                            '(default: every topic)')
    p_rec.add_argument('--use-sim-time', action='store_true',
                       help='stamp the bag with /clock (simulated graphs)')
    p_rep = sub.add_parser('replay', help='publish a bag with its timing and /clock',
                           description='Publish a bag\'s messages with their recorded timing '
                                       'and /clock. Command topics (they can move hardware) '
                                       'are left out unless --include-commands is given.')
    p_rep.add_argument('bag', help=bag_help)
    p_rep.add_argument('--rate', type=non_negative_float, default=1.0,
                       help='speed factor (0 = as fast as possible)')
    p_rep.add_argument('--topic', action='append', metavar='PATTERN',
                       help='topic glob pattern, repeatable (default: every topic except the '
                            'command topics)')
    p_rep.add_argument('--include-commands', action='store_true',
                       help='also publish command topics (can move hardware!)')
    p_rep.add_argument('--no-clock', action='store_true',
                       help='do not publish /clock from the bag\'s stamps')
    p_rep.add_argument('--start-delay', type=non_negative_float, default=2.0,
                       help='wait up to this long [s] for subscribers before playing')
    ns = parser.parse_args(argv)
    try:
        if ns.command == 'info':
            info = bag_info(ns.bag)
            print(info.format())
            if info.message_count == 0:
                raise BagError(f'bag {ns.bag} holds no messages ({len(info.topics)} topic(s) '
                               'declared, none recorded)')
        elif ns.command == 'export':
            validate_bag(ns.bag)
            for path in export_csv(ns.bag, ns.out, ns.topic):
                print(path)
        elif ns.command == 'record':
            from slip_bringup.bag_nodes import recorder_main
            return recorder_main(_ros_args([('output', ns.bag), ('topics', _list(ns.topic)),
                                            ('use_sim_time', str(ns.use_sim_time).lower())]))
        elif ns.command == 'replay':
            validate_bag(ns.bag)
            from slip_bringup.bag_nodes import replay_main
            return replay_main(_ros_args([
                ('bag', ns.bag), ('rate', repr(float(ns.rate))), ('topics', _list(ns.topic)),
                ('include_commands', str(ns.include_commands).lower()),
                ('publish_clock', str(not ns.no_clock).lower()),
                ('start_delay', repr(float(ns.start_delay)))]))
    except (BagError, OSError) as exc:
        print(f'slip_bag: error: {BagError(str(exc))}', file=sys.stderr)
        return 2
    return 0


if __name__ == '__main__':
    sys.exit(main())
