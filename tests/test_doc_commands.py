"""Every command shown in the documentation runs (issue 19): recipes cannot rot.

The fenced ```bash blocks of README.md, docs/**/*.md and src/*/README.md are extracted and
each block is run as one script, in a fresh shell (``env -i``: no inherited environment)
through ``tools/run_ros.sh`` — so the workspace is sourced and the block gets a private ROS
domain — from the repository root, with ``HOME`` in a temporary directory, ``set -e`` and a
time limit. A command that fails fails the block's test, naming the file, the line and the
command. Background jobs a block starts are interrupted when it ends.

Every command line is one of three kinds:

* **run** as written (the default);
* **help-only**: marked in the document with a trailing ``# doc-test: help-only`` comment (or
  listed in `HELP_ONLY` for documents whose blocks this test does not own), for commands
  that run for minutes or forever (``make demo``, ``run_graph``): the command runs with
  ``--help`` appended (``make`` with ``-n``, a dry run), which still checks that the tool
  and its options exist;
* **skipped**, listed in `SKIPPED` below with the reason (hardware-only, destructive, needs a
  full ROS install, placeholders).

Blocks run in parallel, except those of a document marked ``<!-- doc-test: in-order -->``,
which run one after another in document order (later blocks use what earlier ones wrote).

A ``bash`` block is the only kind of code block that may hold commands: an unlabelled block
whose lines start like commands fails `test_unlabelled_blocks_hold_no_commands`, so a recipe
cannot escape these tests by losing its language tag.
"""
from __future__ import annotations

import os
import re
import shlex
import signal
import subprocess
import tempfile
import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MARKER = 'doc-test:'
#: Longest a block may run [s] (the longest, a simulated session, takes about a minute).
BLOCK_TIMEOUT_S = 240.0
#: Blocks run in parallel, each in its own shell and ROS domain.
WORKERS = 3

# ---------------------------------------------------------------------------------- the tables
#: (document, command) → why it is not run here. ``*`` as the document: any document.
SKIPPED: dict[tuple[str, str], str] = {
    ('*', 'make test'): 'the whole test suite, which includes this test',
    ('*', 'make clean'): 'deletes the venv and the build this test runs in',
    ('*', 'make lock'): 'rewrites constraints.txt in the working tree',
    ('*', 'make bags'): 'rewrites the committed reference bags in bags/',
    ('README.md', 'ros2 run <package> <executable> --ros-args --params-file '
                  'src/<package>/config/<node>.yaml'):
        'a template with placeholders; needs the ros2 CLI of a full ROS install',
    ('README.md', 'install/<pkg>/lib/<pkg>/<executable> --ros-args --params-file '
                  'install/<pkg>/share/<pkg>/config/<node>.yaml'):
        'a template with placeholders (the driver READMEs run concrete instances of it)',
    ('*', 'tools/run_ros.sh CMD ...'): 'a template: CMD is a placeholder',
    ('docs/foxglove/README.md', 'export ROS_DOMAIN_ID=<the cell\'s domain> '
                                'ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST'):
        'a template: the domain of the running cell is a placeholder',
    ('docs/hardware_first_run.md',
     'ros2 launch slip_bringup cell.launch.py params_file:=$HOME/slip_site/site.yaml'):
        'needs ros2 launch (full ROS install) and the hardware',
    ('src/slip_bringup/README.md', 'ros2 launch slip_bringup sim_cell.launch.py'):
        'needs ros2 launch (full ROS install); the same graph runs with run_graph --sim above',
    ('docs/hardware_first_run.md',
     'echo "$USER - rtprio 20" | sudo tee /etc/security/limits.d/99-slip-cell.conf'):
        'changes the system configuration (needs root)',
    ('docs/hardware_first_run.md', 'slip_cli echo /diagnostics --count 1'):
        'hardware bring-up: needs the running hardware graph',
    ('docs/hardware_first_run.md', 'slip_cli call gripper/home'):
        'hardware bring-up: needs the real gripper (homing against the emulator is tested in '
        'src/slip_gripper_driver/test/test_gripper_homing.py)',
    ('docs/hardware_first_run.md', 'slip_cli call gripper/bias_ft'):
        'hardware bring-up (the rehearsal block above runs the same call against emulators)',
    ('docs/hardware_first_run.md', 'slip_cli echo finger_1/ft/wrench --count 1'):
        'hardware bring-up (the rehearsal block runs it against emulators)',
    ('docs/hardware_first_run.md', 'force_tracking_test run --bag ~/slip_site/force_tracking'):
        'plays a 52 s force profile on a gripper holding an object',
    ('docs/hardware_first_run.md', 'force_tracking_test analyze ~/slip_site/force_tracking'):
        'analyses the recording of the hardware run above',
    ('docs/hardware_first_run.md', 'slip_cli force 5'): 'hardware: needs the gripper and an object',
    ('docs/hardware_first_run.md', 'slip_cli estimate linear 1.0'):
        'hardware: the arm must move the object meanwhile',
    ('docs/hardware_first_run.md', 'slip_cli estimate rotational 1.0'):
        'hardware: the arm must twist the object meanwhile',
    ('docs/hardware_first_run.md', 'slip_cli properties'): 'hardware: reads the estimate above',
    ('docs/hardware_first_run.md', 'slip_cli mode hold'): 'hardware: holds a real object',
    ('docs/hardware_first_run.md', 'slip_cli mode linear --distance 0.02 --duration 2.0'):
        'hardware: slides a real object',
    ('docs/hardware_first_run.md',
     'calibration_recorder --finger 1 --output-dir ~/slip_site/calib'):
        'interactive procedure on a real sensor with a sliding plate (about 12 min)',
    ('docs/hardware_first_run.md',
     'calibration_fit fit ~/slip_site/calib --out-dir ~/slip_site/calibration'):
        'fits the hardware recordings above (the synthetic rehearsal below runs the same fit)',
    ('src/slip_velocity_sensor/README.md',
     'calibration_recorder --finger 1 --output-dir ~/slip_site/calib'):
        'interactive procedure on a real sensor with a sliding plate (about 12 min)',
    ('src/slip_velocity_sensor/README.md',
     'calibration_fit fit ~/slip_site/calib --out-dir ~/slip_site/calibration'):
        'fits the hardware recordings above (docs/hardware_first_run.md runs the fit on '
        'synthetic recordings)',
    ('src/slip_gripper_driver/README.md', 'force_tracking_test run --bag ~/slip_site/sponge_1'):
        'plays a 52 s force profile on a gripper holding an object',
    ('src/slip_gripper_driver/README.md', 'force_tracking_test analyze ~/slip_site/sponge_1'):
        'analyses the recording of the hardware run above',
}

#: (document, command) → why only ``--help`` runs, for documents whose blocks carry no marker
#: (the top-level README and the toolchain reference keep their blocks unannotated).
HELP_ONLY: dict[tuple[str, str], str] = {
    ('*', 'make demo'): 'the full demo takes minutes (docs run slip_demo --help and shorter '
                        'sessions on the simulated graph)',
    ('*', 'make setup'): 'the build; this test runs after it (dry run only)',
    ('*', 'make bench'): 'every benchmark, minutes',
    ('*', 'make lint'): 'ruff and mypy over the workspace, run by CI itself',
    ('docs/foxglove/README.md', 'foxglove_live'): 'a server that runs until stopped',
    ('docs/evaluation.md', 'slip_evaluate'): 'every reference object, about a minute',
    ('docs/evaluation.md', 'slip_evaluate --truth-properties'):
        'every reference object, about a minute',
    ('docs/evaluation.md', 'slip_evaluate --population 200 --seed 11'):
        '200 objects: many minutes',
    ('docs/evaluation.md', 'slip_evaluate --population 200 --seed 11 --controllers thesis,model'):
        '200 objects and two law families: many minutes',
    ('docs/evaluation.md',
     'slip_evaluate --population 200 --seed 11 --scheduler tcp://scheduler:8786'):
        'needs a Dask scheduler at that address',
}

# ---------------------------------------------------------------------------------- parsing
FENCE = re.compile(r'^(?P<indent> {0,3})```(?P<lang>[\w+-]*)\s*$')
HEREDOC = re.compile(r"<<-?\s*(['\"]?)(?P<tag>\w+)\1")
SHELL_LANGS = {'bash', 'sh', 'shell'}


@dataclass(frozen=True)
class Command:
    """One logical command line of a block (continuations joined, heredoc body attached)."""

    text: str          # the command, comment stripped, continuations joined by single spaces
    script: str        # what the shell runs (heredoc body included)
    line: int          # 1-based line in the document
    help_only: bool    # marked ``# doc-test: help-only``


@dataclass(frozen=True)
class Block:
    """A fenced code block of a document."""

    doc: str           # path relative to the repository root
    line: int          # 1-based line of the opening fence
    lang: str
    lines: tuple[str, ...]
    commands: tuple[Command, ...] = field(default=())

    @property
    def id(self) -> str:
        return f'{self.doc}:{self.line}'


def doc_files(root: Path = ROOT) -> list[Path]:
    """The documents whose commands are checked."""
    files = [root / 'README.md', *sorted((root / 'docs').rglob('*.md')),
             *sorted(root.glob('src/*/README.md'))]
    return [f for f in files if f.is_file()]


def strip_comment(line: str) -> tuple[str, str]:
    """``(code, comment)`` of one shell line: a ``#`` outside quotes after whitespace."""
    quote = ''
    for i, ch in enumerate(line):
        if quote:
            if ch == quote:
                quote = ''
            elif ch == '\\' and quote == '"':
                continue
        elif ch in '\'"':
            quote = ch
        elif ch == '#' and (i == 0 or line[i - 1] in ' \t'):
            return line[:i].rstrip(), line[i + 1:].strip()
    return line.rstrip(), ''


def parse_commands(lines: tuple[str, ...], first_line: int) -> tuple[Command, ...]:
    """Split a bash block into logical commands (see `Command`)."""
    out: list[Command] = []
    i = 0
    while i < len(lines):
        start = i
        code, comment = strip_comment(lines[i])
        marks = [comment]
        parts = [code]
        raw = [lines[i]]
        while parts[-1].endswith('\\') and i + 1 < len(lines):
            parts[-1] = parts[-1][:-1].rstrip()
            i += 1
            code, comment = strip_comment(lines[i])
            parts.append(code.strip())
            raw.append(lines[i])
            marks.append(comment)
        i += 1
        text = ' '.join(p for p in parts if p).strip()
        if not text:
            continue
        script = '\n'.join(raw)
        heredoc = HEREDOC.search(text)
        if heredoc:
            tag = heredoc.group('tag')
            body = []
            while i < len(lines) and lines[i].strip() != tag:
                body.append(lines[i])
                i += 1
            if i == len(lines):
                raise ValueError(f'line {first_line + start + 1}: heredoc {tag} never ends')
            script += '\n' + '\n'.join(body + [lines[i]])
            i += 1
        help_only = any(m.startswith(MARKER) and 'help-only' in m for m in marks)
        unknown = [m for m in marks if m.startswith(MARKER) and m != f'{MARKER} help-only']
        if unknown:
            raise ValueError(f'line {first_line + start + 1}: unknown marker {unknown[0]!r} '
                             f'(only "# {MARKER} help-only" exists)')
        out.append(Command(text, script, first_line + start + 1, help_only))
    return tuple(out)


def parse_blocks(path: Path, root: Path = ROOT) -> list[Block]:
    """Every fenced block of a Markdown file, with the commands of the shell ones."""
    text = path.read_text().splitlines()
    doc = str(path.relative_to(root))
    blocks: list[Block] = []
    i = 0
    while i < len(text):
        m = FENCE.match(text[i])
        if not m:
            i += 1
            continue
        start, lang, body = i, m.group('lang'), []
        i += 1
        while i < len(text) and not text[i].strip().startswith('```'):
            body.append(text[i])
            i += 1
        i += 1
        lines = tuple(body)
        commands = parse_commands(lines, start + 1) if lang in SHELL_LANGS else ()
        blocks.append(Block(doc, start + 1, lang, lines, commands))
    return blocks


def _lookup(table: dict[tuple[str, str], str], doc: str, command: str) -> str | None:
    return table.get((doc, command), table.get(('*', command)))


def help_variant(command: Command) -> str:
    """The help-only form: ``--help`` appended (``make``: a dry run with ``-n``)."""
    if HEREDOC.search(command.text) or '|' in command.text or command.text.endswith('&'):
        raise ValueError(f'line {command.line}: help-only needs a single plain command, not '
                         f'{command.text!r}')
    words = shlex.split(command.text)
    if words[0] == 'make':
        return 'make -n ' + ' '.join(shlex.quote(w) for w in words[1:])
    return command.text + ' --help'


def block_script(block: Block) -> tuple[str, list[tuple[Command, str]]]:
    """The script that runs ``block`` and the commands in it with how each runs.

    Each command is preceded by a line that prints ``@@doc-test <index>`` to stderr, so a
    failure is traced to its command.
    """
    planned: list[tuple[Command, str]] = []
    body = ['set -eo pipefail',
            # Interrupt what the block left running in the background (nodes, emulators).
            # Nodes get up to 10 s to stop (run_graph passes SIGINT on to its nodes).
            "trap 'rc=$?; set +e; jobs -p | xargs -r kill -INT 2>/dev/null; "
            "for _ in $(seq 100); do "
            "[ -z \"$(jobs -pr)\" ] && break; sleep 0.1; done; "
            "jobs -p | xargs -r kill -KILL 2>/dev/null; wait; exit $rc' EXIT",
            f'cd {shlex.quote(str(ROOT))}']
    for command in block.commands:
        if _lookup(SKIPPED, block.doc, command.text) is not None:
            planned.append((command, 'skipped'))
            continue
        help_only = command.help_only or _lookup(HELP_ONLY, block.doc, command.text) is not None
        run = help_variant(command) if help_only else command.script
        planned.append((command, 'help-only' if help_only else 'run'))
        body.append(f'echo "@@doc-test {len(planned) - 1}" >&2')
        body.append(run)
    return '\n'.join(body) + '\n', planned


# ---------------------------------------------------------------------------------- running
@dataclass(frozen=True)
class BlockResult:
    returncode: int
    output: str
    failed: str          # the command that was running when the block failed ('' if none)
    seconds: float


def run_script(script: str, planned: list[tuple[Command, str]], home: Path,
               timeout_s: float = BLOCK_TIMEOUT_S) -> BlockResult:
    """Run a block script in a fresh shell through tools/run_ros.sh."""
    path = home / 'block.sh'
    path.write_text(script)
    # XDG_RUNTIME_DIR of its own: blocks run in parallel, and the velocity-sensor nodes claim
    # their sensor's name host-wide there (two blocks would look like two boards named alike).
    runtime = home / 'run'
    runtime.mkdir(exist_ok=True)
    env = {'HOME': str(home), 'PATH': '/usr/bin:/bin', 'LANG': 'C.UTF-8', 'TERM': 'dumb',
           'PYTHONUNBUFFERED': '1', 'XDG_RUNTIME_DIR': str(runtime)}
    cmd = ['env', '-i', *[f'{k}={v}' for k, v in env.items()],
           str(ROOT / 'tools' / 'run_ros.sh'), 'bash', '--noprofile', '--norc', str(path)]
    started = time.monotonic()
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            start_new_session=True, text=True, errors='replace')
    try:
        output, _ = proc.communicate(timeout=timeout_s)
        code = proc.returncode
    except subprocess.TimeoutExpired:
        _stop_group(proc)
        output, _ = proc.communicate()
        output += f'\n(block killed after {timeout_s:.0f} s)'
        code = -1
    finally:
        _stop_group(proc)
    marks = re.findall(r'^@@doc-test (\d+)$', output, re.M)
    failed = ''
    if code != 0 and marks:
        command, how = planned[int(marks[-1])]
        failed = f'line {command.line} ({how}): {command.text}'
    return BlockResult(code, output, failed, time.monotonic() - started)


def _stop_group(proc: subprocess.Popen[str]) -> None:
    """SIGINT the block's process group (nodes shut down cleanly), then SIGKILL it."""
    for sig, grace in ((signal.SIGINT, 10.0), (signal.SIGKILL, 5.0)):
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            return
        deadline = time.monotonic() + grace
        while time.monotonic() < deadline:
            try:
                os.killpg(proc.pid, 0)
            except ProcessLookupError:
                return
            time.sleep(0.1)


# ---------------------------------------------------------------------------------- collection
BLOCKS = [b for f in doc_files() for b in parse_blocks(f)]
SHELL_BLOCKS = [b for b in BLOCKS if b.lang in SHELL_LANGS and b.commands]
RUNNABLE = [b for b in SHELL_BLOCKS
            if any(how != 'skipped' for _, how in block_script(b)[1])]
#: A document holding this comment has its blocks run one after another, in document order
#: (a later block uses files an earlier one wrote, as a reader running them would).
IN_ORDER_MARK = '<!-- doc-test: in-order -->'
IN_ORDER_DOCS = {str(p.relative_to(ROOT)) for p in doc_files() if IN_ORDER_MARK in p.read_text()}


def _cost(block: Block) -> int:
    """Rough order of cost, so the long blocks start first."""
    text = '\n'.join(c.text for c in block.commands)
    return -(100 * text.count('run_graph') + 50 * text.count('emulator') + len(block.commands))


def _run_chain(blocks: list[Block], homes: list[Path],
               futures: list[Future[BlockResult]]) -> None:
    """Run ``blocks`` one after another (each in its own home), setting each one's future."""
    for block, home, future in zip(blocks, homes, futures):
        try:
            script, planned = block_script(block)
            future.set_result(run_script(script, planned, home))
        except BaseException as exc:  # handed to the waiting test
            future.set_exception(exc)


class _Runs:
    """Runs the selected blocks in parallel, once per session; tests wait for their block."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._futures: dict[str, Future[BlockResult]] = {}
        self._pool: ThreadPoolExecutor | None = None
        self._tmp = tempfile.TemporaryDirectory(prefix='slip_doc_test_')

    def start(self, blocks: list[Block]) -> None:
        with self._lock:
            if self._pool is not None:
                return
            self._pool = ThreadPoolExecutor(max_workers=WORKERS)
            # One job per block, except the blocks of an in-order document: one job runs
            # those one after another, in the order a reader runs them.
            jobs: list[list[Block]] = []
            chains: dict[str, list[Block]] = {}
            for block in sorted(blocks, key=lambda b: b.line):
                if block.doc in IN_ORDER_DOCS:
                    if block.doc not in chains:
                        chains[block.doc] = []
                        jobs.append(chains[block.doc])
                    chains[block.doc].append(block)
                else:
                    jobs.append([block])
            jobs.sort(key=lambda job: sum(_cost(b) for b in job))
            n = 0
            for job in jobs:
                futures: list[Future[BlockResult]] = []
                homes = []
                for block in job:
                    homes.append(Path(self._tmp.name) / f'home_{n}')
                    homes[-1].mkdir()
                    n += 1
                    futures.append(Future())
                    self._futures[block.id] = futures[-1]
                self._pool.submit(_run_chain, job, homes, futures)

    def result(self, block: Block) -> BlockResult:
        return self._futures[block.id].result()

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            print('\ndoc-command blocks (wall time):')
            for block_id, future in sorted(self._futures.items(),
                                           key=lambda kv: -kv[1].result().seconds):
                r = future.result()
                print(f'  {r.seconds:6.1f} s  exit {r.returncode:3d}  {block_id}')
        self._tmp.cleanup()


@pytest.fixture(scope='module')
def runs(request: pytest.FixtureRequest):
    selected = {item.callspec.params['block'].id for item in request.session.items
                if getattr(item, 'callspec', None) and 'block' in item.callspec.params
                and item.originalname == 'test_documented_commands_run'}
    runner = _Runs()
    runner.start([b for b in RUNNABLE if b.id in selected])
    yield runner
    runner.close()


@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.parametrize('block', RUNNABLE, ids=lambda b: b.id)
def test_documented_commands_run(block: Block, runs: _Runs) -> None:
    result = runs.result(block)
    tail = '\n'.join(result.output.splitlines()[-60:])
    assert result.returncode == 0, (
        f'{block.id}: a documented command failed (exit {result.returncode}) — '
        f'{result.failed or "before the first command"}\n--- last output ---\n{tail}')


# ---------------------------------------------------------------------------------- coverage
def test_the_documents_show_commands() -> None:
    docs = {b.doc for b in SHELL_BLOCKS}
    for expected in ('README.md', 'docs/hardware_first_run.md', 'docs/adding_an_object.md',
                     'src/slip_control/README.md', 'src/slip_gripper_driver/README.md'):
        assert expected in docs, f'{expected} shows no bash block'
    assert len(RUNNABLE) >= 15


def test_every_table_entry_names_a_documented_command() -> None:
    """No stale entries: each skip or help-only entry still matches a command shown."""
    shown = {(b.doc, c.text) for b in SHELL_BLOCKS for c in b.commands}
    texts = {c for _, c in shown}
    for table in (SKIPPED, HELP_ONLY):
        for doc, command in table:
            found = command in texts if doc == '*' else (doc, command) in shown
            assert found, f'table entry ({doc!r}, {command!r}) matches no documented command'


def test_skipped_commands_say_why() -> None:
    for key, reason in {**SKIPPED, **HELP_ONLY}.items():
        assert len(reason) > 15, key


#: Box-drawing characters and arrows: a line with one is part of a diagram.
DIAGRAM = re.compile('[\u2500-\u257f\u2190-\u21ff\u25b2-\u25c4]')
#: First words that make a line of an unlabelled block look like a command.
COMMAND_WORDS = {'make', 'source', 'export', 'ros2', 'colcon', 'python', 'python3', 'pip',
                 'cd', 'sudo', 'tools/run_ros.sh', '.venv/bin/python', 'PYTHONPATH'}


def _console_scripts() -> set[str]:
    names = {p.name for p in (ROOT / 'src' / 'slip_bringup' / 'bin').glob('*')}
    for setup in ROOT.glob('src/*/setup.py'):
        names |= set(re.findall(r"'(\w+) = [\w.]+:\w+'", setup.read_text()))
    return names


def test_unlabelled_blocks_hold_no_commands() -> None:
    words = COMMAND_WORDS | _console_scripts()
    assert {'run_graph', 'slip_cli', 'gripper_driver'} <= words
    bad = []
    for block in BLOCKS:
        if block.lang:
            continue
        for offset, line in enumerate(block.lines):
            if DIAGRAM.search(line):
                continue  # a drawing of the graph, not a command
            tokens = line.strip().split()
            if not tokens or (len(tokens) > 1 and tokens[1].startswith('(')):
                continue  # prose: "node (package) does ..."
            if tokens[0].split('=')[0] in words:
                bad.append(f'{block.doc}:{block.line + 1 + offset}: {line.strip()}')
    assert not bad, 'commands in code blocks without a language (label them ```bash):\n' + \
        '\n'.join(bad)


# ---------------------------------------------------------------------------------- the checker
def test_parser_joins_continuations_attaches_heredocs_and_reads_markers() -> None:
    lines = ('cat > /tmp/x.yaml <<\'EOF\'', 'a: 1  # a comment in the body', 'EOF',
             'run_graph --sim \\', '    --duration 5   # doc-test: help-only',
             "sed 's|#|x|' file   # trailing comment", '', '# a comment line')
    commands = parse_commands(lines, 10)
    assert [c.text for c in commands] == [
        "cat > /tmp/x.yaml <<'EOF'", 'run_graph --sim --duration 5', "sed 's|#|x|' file"]
    assert [c.line for c in commands] == [11, 14, 16]
    assert commands[0].script.endswith('a: 1  # a comment in the body\nEOF')
    assert [c.help_only for c in commands] == [False, True, False]
    assert help_variant(commands[1]) == 'run_graph --sim --duration 5 --help'
    assert help_variant(Command('make demo DEMO_ARGS="--preset wood"', '', 1, True)) == \
        "make -n demo 'DEMO_ARGS=--preset wood'"
    with pytest.raises(ValueError, match='unknown marker'):
        parse_commands(('slip_cli force 5  # doc-test: skip',), 1)


def test_blocks_of_an_in_order_document_run_one_after_another(tmp_path: Path) -> None:
    """The second block reads what the first wrote (it starts only when the first ended)."""
    shared = tmp_path / 'shared.txt'
    first = Block('docs/probe.md', 1, 'bash', (), parse_commands((
        'sleep 1', f'echo written > {shared}'), 2))
    second = Block('docs/probe.md', 10, 'bash', (), parse_commands((f'cat {shared}',), 11))
    homes = [tmp_path / 'home_0', tmp_path / 'home_1']
    for home in homes:
        home.mkdir()
    futures: list[Future[BlockResult]] = [Future(), Future()]
    _run_chain([first, second], homes, futures)
    assert futures[0].result().returncode == 0, futures[0].result().output
    assert futures[1].result().returncode == 0, futures[1].result().output
    assert 'written' in futures[1].result().output
    assert 'docs/adding_an_object.md' in IN_ORDER_DOCS


def test_a_failing_command_fails_its_block(tmp_path: Path) -> None:
    """The runner reports the command that broke, in a fresh shell with the workspace."""
    block = Block('docs/probe.md', 1, 'bash', (), parse_commands((
        'echo "$HOME" > "$HOME/home.txt"',
        'slip_bag --help   # doc-test: help-only',
        'slip_bag info /nonexistent/bag',
        'echo never reached'), 1))
    script, planned = block_script(block)
    result = run_script(script, planned, tmp_path, timeout_s=60.0)
    assert result.returncode != 0
    assert result.failed == 'line 4 (run): slip_bag info /nonexistent/bag', result.output
    assert 'never reached' not in result.output
    assert (tmp_path / 'home.txt').read_text().strip() == str(tmp_path)  # HOME is the temp dir


def test_a_skipped_command_is_not_run(tmp_path: Path) -> None:
    block = Block('README.md', 1, 'bash', (), parse_commands(
        ('make clean', 'echo ran > "$HOME/ran.txt"'), 2))
    script, planned = block_script(block)
    assert [how for _, how in planned] == ['skipped', 'run']
    assert 'make clean' not in script
    assert run_script(script, planned, tmp_path, timeout_s=60.0).returncode == 0
    assert (tmp_path / 'ran.txt').is_file()
