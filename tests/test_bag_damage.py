"""Every damaged or foreign input to every bag tool: one-line error naming it, non-zero exit.

The tools run in-process through their ``main(argv)`` (``slip_bag info/export/replay``,
``slip_analyze``); a traceback, a silent empty result or a zero exit fails the test. Damage is
made to real bags written by `BagWriter` (tests/support/sample_bags.py).
"""
from __future__ import annotations

import re
import shutil
from pathlib import Path
from collections.abc import Callable

import pytest

from support.sample_bags import write_sample_bag


def _bag(tmp: Path, n: int = 400) -> Path:
    bag = tmp / 'bag'
    write_sample_bag(bag, n=n)
    return bag


def _mcap(bag: Path) -> Path:
    return next(bag.glob('*.mcap'))


def missing_path(tmp: Path) -> Path:
    return tmp / 'no_such_bag'


def empty_folder(tmp: Path) -> Path:
    (tmp / 'empty').mkdir()
    return tmp / 'empty'


def folder_without_metadata(tmp: Path) -> Path:
    bag = _bag(tmp)
    (bag / 'metadata.yaml').unlink()
    return bag


def non_bag_folder(tmp: Path) -> Path:
    folder = tmp / 'photos'
    folder.mkdir()
    (folder / 'notes.txt').write_text('not a bag\n')
    (folder / 'data.csv').write_text('a,b\n1,2\n')
    return folder


def plain_file(tmp: Path) -> Path:
    path = tmp / 'bag.csv'
    path.write_text('a,b\n1,2\n')
    return path


def invalid_metadata_yaml(tmp: Path) -> Path:
    bag = _bag(tmp)
    (bag / 'metadata.yaml').write_text('rosbag2_bagfile_information: {version: [}\n')
    return bag


def foreign_metadata_yaml(tmp: Path) -> Path:
    bag = _bag(tmp)
    (bag / 'metadata.yaml').write_text('my_node:\n  ros__parameters:\n    rate: 10.0\n')
    return bag


def missing_data_file(tmp: Path) -> Path:
    bag = _bag(tmp)
    _mcap(bag).unlink()
    return bag


def truncated_mcap(tmp: Path) -> Path:
    bag = _bag(tmp)
    data = _mcap(bag)
    data.write_bytes(data.read_bytes()[: data.stat().st_size // 2])
    return bag


def bit_flipped_chunk(tmp: Path) -> Path:
    from mcap.reader import make_reader
    bag = _bag(tmp)
    data = _mcap(bag)
    with data.open('rb') as fh:
        chunk = make_reader(fh).get_summary().chunk_indexes[0]
    raw = bytearray(data.read_bytes())
    at = chunk.chunk_start_offset + chunk.chunk_length // 2
    raw[at] ^= 0x10
    data.write_bytes(bytes(raw))
    return bag


def inflated_metadata_counts(tmp: Path) -> Path:
    bag = _bag(tmp)
    meta = bag / 'metadata.yaml'
    text = meta.read_text()
    text, n = re.subn(r'message_count: 400\b', 'message_count: 4000', text)
    assert n == 1, 'the sample bag metadata changed; adapt the edit'
    text = re.sub(r'message_count: 441\b', 'message_count: 4041', text)
    meta.write_text(text)
    return bag


def zero_message_bag(tmp: Path) -> Path:
    from slip_cell_common.bag_io import BagWriter
    bag = tmp / 'silent'
    with BagWriter(bag) as writer:
        writer.add_topic('/gripper/status', 'slip_msgs/msg/GripperStatus')
    return bag


DAMAGE: dict[str, tuple[Callable[[Path], Path], str]] = {
    'missing_path': (missing_path, 'does not exist'),
    'empty_folder': (empty_folder, 'empty folder'),
    'folder_without_metadata': (folder_without_metadata, 'no metadata.yaml'),
    'non_bag_folder': (non_bag_folder, 'not a rosbag2 bag'),
    'plain_file': (plain_file, 'not a rosbag2 bag folder'),
    'invalid_metadata_yaml': (invalid_metadata_yaml, 'metadata.yaml'),
    'foreign_metadata_yaml': (foreign_metadata_yaml, 'rosbag2_bagfile_information'),
    'missing_data_file': (missing_data_file, 'missing'),
    'truncated_mcap': (truncated_mcap, 'truncated'),
    'bit_flipped_chunk': (bit_flipped_chunk, 'corrupt'),
    'inflated_metadata_counts': (inflated_metadata_counts, 'counts disagree with the data'),
    'zero_message_bag': (zero_message_bag, 'no messages'),
}


def _slip_bag(command: str) -> Callable[[Path, Path], int]:
    def run(bag: Path, tmp: Path) -> int:
        from slip_bringup.bag_cli import main
        extra = ['--out', str(tmp / 'csv')] if command == 'export' else []
        if command == 'replay':
            extra = ['--start-delay', '0']
        return main([command, str(bag), *extra])
    return run


def _slip_analyze(bag: Path, tmp: Path) -> int:
    from slip_bringup.analyze import main
    return main([str(bag), '--out', str(tmp / 'report'), '--no-plots'])


TOOLS: dict[str, Callable[[Path, Path], int]] = {
    'info': _slip_bag('info'), 'export': _slip_bag('export'), 'replay': _slip_bag('replay'),
    'analyze': _slip_analyze,
}


@pytest.mark.parametrize('tool', sorted(TOOLS))
@pytest.mark.parametrize('damage', sorted(DAMAGE))
def test_damaged_bag_gives_one_line_error(damage: str, tool: str, tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    make, expected = DAMAGE[damage]
    bag = make(tmp_path)
    capsys.readouterr()
    code = TOOLS[tool](bag, tmp_path)
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert code != 0, f'{tool} accepted a {damage}'
    assert len(lines) == 1, f'{tool} on {damage} printed {len(lines)} lines:\n{err}'
    assert 'Traceback' not in err
    assert expected in lines[0], lines[0]
    assert not (tmp_path / 'csv').exists() or not any((tmp_path / 'csv').iterdir()), \
        'export wrote files from a damaged bag'


def test_analyze_lists_every_missing_topic(tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    from slip_bringup.analyze import main
    from slip_cell_common.bag_io import BagWriter
    from rclpy.serialization import serialize_message
    from support.sample_bags import status_message
    bag = tmp_path / 'status_only'
    with BagWriter(bag) as writer:
        writer.add_topic('/gripper/status', 'slip_msgs/msg/GripperStatus')
        for k in range(20):
            writer.write('/gripper/status', 1_000_000 * (k + 1),
                         serialize_message(status_message(k)))
    assert main([str(bag), '--no-plots']) == 2
    err = capsys.readouterr().err.strip()
    assert '\n' not in err
    assert '/gripper/grasp_force_cmd' in err and '/gripper/motor_command' in err


def test_intact_bag_passes_every_tool_but_replay(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """The checks above are not simply failing every bag: an intact bag passes info and
    export, and analyze fails only for its missing topics."""
    bag = _bag(tmp_path)
    assert TOOLS['info'](bag, tmp_path) == 0
    assert TOOLS['export'](bag, tmp_path) == 0
    assert len(list((tmp_path / 'csv').glob('*.csv'))) == 3
    capsys.readouterr()
    assert TOOLS['analyze'](bag, tmp_path) == 2
    assert '/gripper/motor_command' in capsys.readouterr().err
    shutil.rmtree(tmp_path / 'csv')


@pytest.mark.ros
@pytest.mark.parametrize('damage', ['missing_path', 'folder_without_metadata',
                                    'bit_flipped_chunk', 'inflated_metadata_counts',
                                    'zero_message_bag'])
def test_bag_replay_node_refuses_a_damaged_bag_before_publishing(damage: str,
                                                                 tmp_path: Path) -> None:
    """The installed ``bag_replay`` console script (not only ``slip_bag replay``) reads the
    whole bag before it publishes: one error line, non-zero exit, no traceback."""
    import subprocess

    from slip_cell_common.testing import workspace_root
    make, expected = DAMAGE[damage]
    bag = make(tmp_path)
    exe = workspace_root() / 'install' / 'slip_bringup' / 'lib' / 'slip_bringup' / 'bag_replay'
    done = subprocess.run([str(exe), '--ros-args', '-p', f'bag:={bag}', '-p',
                           'start_delay:=0.0'], capture_output=True, text=True, timeout=60)
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert done.returncode != 0, f'bag_replay accepted a {damage}: {done.stdout}'
    assert 'Traceback' not in done.stderr
    assert len(lines) == 1 and expected in lines[0], done.stderr
    assert 'replay finished' not in done.stdout + done.stderr
