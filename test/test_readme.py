"""Every command line of the ```bash blocks of the README and of the manual's pages in docs/ runs and does its job,
so the manual cannot drift (docs/_incoming/, a staging area, is not the manual).

Each line runs with bash in a scratch copy of the checkout (the venv, package and scripts linked, the sample bags
copied), so what it writes (bags, pictures, CSV) lands there. A command runs until it ends by itself or, once it
has shown it started (bringup's `running` line, any output of another node), for at most NATURAL_RUN wall seconds;
then it gets Ctrl-C, as a user would stop it. Either way it must exit 0 without a traceback and leave the sign of
its work (a summary, a closed bag, a picture, a CSV). Nothing is timed: the budget only bounds the suite.

The one documented exception: `scripts/test.sh` would run this very suite again; it runs with `--collect-only -n 0
--no-cov` (it still sets up, sources the environment and must collect the tests; in one process, without coverage:
collecting in three processes under coverage took 40 s of a loaded run).

The commands run in one scratch checkout, as a reader would type them: the README's in its order, then each page's
in the order the README links the pages (manual_pages.pages). One may read what an earlier one wrote
(`bag summary bags/headless_avoid` after the run that records it, on a later page than the README's), so
scripts/test.sh keeps a test file in one process (`--dist loadfile`). A command shown on several pages (the
README's tour repeats some of the manual's) runs once, where it first appears.
"""
from __future__ import annotations

import os
import re
import shlex
import shutil
import signal
import subprocess
import time
from pathlib import Path

import pytest
from conftest import BIN_DIR, processes_in_this_domain
from manual_pages import README, ROOT, pages

LINKED = ('.venv', 'epuck_ros', 'scripts', 'requirements.txt', 'setup.py', 'setup.cfg', 'package.xml', 'resource',
          'docs', 'benchmarks', 'test')
COPIED = ('bags',)
START_TIMEOUT = 120.0
"""Wall seconds for a command to show it started, on a loaded machine."""
NATURAL_RUN = 2.0
"""Wall seconds a started command may go on before it is interrupted (bounds the suite, decides nothing)."""
INTERRUPTED_EXIT_130 = ('sweep', 'evolve')
"""The commands that keep what they did, say they were interrupted and exit 130 after Ctrl-C (the rest exit 0)."""
FINISHED = {'sweep': re.compile(r'\[sweep\] (\d+)/\1 trials'), 'evolve': re.compile(r'\[evolve\] \d+ generations')}
"""What a sweep and an evolve print once all their work is done."""
STOP_TIMEOUT = 60.0
BRINGUP = re.compile(r'(^|[\s/])(bringup|run\.sh)\s')
RECURSIVE = 'scripts/test.sh'


def readme_commands(text: str) -> list[str]:
    r"""The command lines of a page's ```bash blocks (comments and blank lines dropped; `\` continuations joined)."""
    commands: list[str] = []
    for block in re.findall(r'^```bash\n(.*?)^```', text, flags=re.S | re.M):
        for line in block.replace('\\\n', ' ').splitlines():
            command = _without_comment(line).strip()
            if command:
                commands.append(command)
    return commands


def _without_comment(line: str) -> str:
    """The line up to a `#` that starts a shell comment: outside quotes, at the start of a word."""
    quote = ''
    for index, char in enumerate(line):
        if quote:
            quote = '' if char == quote else quote
        elif char in '\'"':
            quote = char
        elif char == '#' and (index == 0 or line[index - 1].isspace()):
            return line[:index]
    return line


def manual_commands() -> list[str]:
    """Every page's command lines in reading order, each once (where it first appears)."""
    commands: dict[str, str] = {}
    for page in pages():
        for command in readme_commands(page.read_text()):
            commands.setdefault(' '.join(command.split()), command)
    return list(commands.values())


COMMANDS = manual_commands()


@pytest.fixture(scope='module')
def workspace(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A scratch checkout: the venv and sources linked, the sample bags copied (commands write next to them)."""
    root = tmp_path_factory.mktemp('readme')
    for name in LINKED:
        if (ROOT / name).exists():
            (root / name).symlink_to(ROOT / name)
    for name in COPIED:
        if (ROOT / name).exists():
            shutil.copytree(ROOT / name, root / name)
    return root


def test_the_readme_has_commands_to_check():
    assert len(COMMANDS) >= 10, COMMANDS
    assert any(BRINGUP.search(command + ' ') for command in COMMANDS)
    assert {'scripts/run.sh', RECURSIVE} <= set(readme_commands(README.read_text())), 'the two commands'
    assert sum(len(readme_commands(page.read_text())) for page in pages()[1:]) >= 10, 'the pages of docs/ too'


@pytest.mark.parametrize('command', COMMANDS)
def test_readme_command(command: str, workspace: Path, tmp_path: Path) -> None:
    if command.split()[0] == RECURSIVE:
        command += ' --collect-only -q -n 0 --no-cov'
    log_path = tmp_path / 'output.log'
    env = dict(os.environ, PATH=f'{BIN_DIR}{os.pathsep}{os.environ["PATH"]}', PYTHONUNBUFFERED='1')
    with open(log_path, 'w') as log:
        process = subprocess.Popen(['bash', '-c', command], cwd=workspace, stdout=log, stderr=subprocess.STDOUT,
                                   env=env, start_new_session=True)
    try:
        interrupted = _run_bounded(process, command, log_path)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    output = log_path.read_text()
    # Ctrl-C ends a sweep or an evolve as shells expect of a process a signal ended (the README: exit 130). A
    # Ctrl-C that reaches one after its last trial or generation (it says it finished, not that it was
    # interrupted) cuts nothing, and 0 is right: which of the two happened is the command's to say, not the clock's.
    cut_short = interrupted and command.split()[0] in INTERRUPTED_EXIT_130 and 'interrupted' in output
    expected = 130 if cut_short else 0
    assert process.returncode == expected, f'{command!r} exited with {process.returncode}:\n{output}'
    if interrupted and not cut_short and command.split()[0] in INTERRUPTED_EXIT_130:
        assert FINISHED[command.split()[0]].search(output), f'{command!r} ignored Ctrl-C mid-work:\n{output}'
    assert 'Traceback' not in output, output
    _check_sign_of_work(command, output, workspace, interrupted)
    assert processes_in_this_domain() == [], f'{command!r} left processes behind'


def _run_bounded(process: subprocess.Popen, command: str, log_path: Path) -> bool:
    """Let the command end by itself, or interrupt it once it has started and run a while; True if interrupted.
    The suite's own command (collecting only) ends by itself: its first lines come long before its last."""
    if command.split()[0] == RECURSIVE:
        try:
            process.wait(START_TIMEOUT)
        except subprocess.TimeoutExpired:
            pytest.fail(f'{command!r} did not end within {START_TIMEOUT:.0f} s:\n{log_path.read_text()}')
        return False
    started_sign = '[bringup] running' if BRINGUP.search(command + ' ') else ''
    deadline = time.monotonic() + START_TIMEOUT
    started_at = None
    while process.poll() is None:
        now = time.monotonic()
        if started_at is None:
            output = log_path.read_text()
            if (started_sign and started_sign in output) or (not started_sign and output.strip()):
                started_at = now
            elif now > deadline:
                pytest.fail(f'{command!r} showed no sign of starting within {START_TIMEOUT:.0f} s:\n{output}')
        elif now - started_at > NATURAL_RUN and '[bringup] simulated' not in log_path.read_text():
            os.killpg(process.pid, signal.SIGINT)  # Ctrl-C in the terminal reaches the whole foreground group
            try:
                process.wait(STOP_TIMEOUT)
            except subprocess.TimeoutExpired:
                pytest.fail(f'{command!r} did not stop within {STOP_TIMEOUT:.0f} s of Ctrl-C:\n'
                            f'{log_path.read_text()}')
            return True
        time.sleep(0.1)
    return False


def _check_sign_of_work(command: str, output: str, workspace: Path, interrupted: bool) -> None:
    words = shlex.split(command, comments=True)
    if words[0] == RECURSIVE:
        assert re.search(r'\d+ tests? collected', output), output
        return
    if BRINGUP.search(command + ' ') and '--help' not in words:
        assert '[bringup] simulated' in output, output  # the summary: it ran and stopped everything
    for flag in ('--record', '-o', '--output'):
        if flag in words and words.index(flag) + 1 < len(words) and not words[words.index(flag) + 1].startswith('-'):
            target = workspace / words[words.index(flag) + 1]
            assert target.exists(), f'{command!r} did not write {target}:\n{output}'
            if target.is_dir() and words[0] == 'sweep':
                assert (target / 'trials.csv').is_file(), f'{target} has no trials.csv:\n{output}'
            elif target.is_dir() and words[0] == 'evolve':
                assert (target / 'fitness.csv').is_file(), f'{target} has no fitness.csv:\n{output}'
            elif target.is_dir():
                assert (target / 'metadata.yaml').is_file(), f'{target} is not a closed bag:\n{output}'
            else:
                assert target.stat().st_size > 0, f'{target} is empty'
    if words[0] == 'bag' and len(words) > 1 and words[1] in ('info', 'summary'):
        assert output.strip(), f'{command!r} printed nothing'
    if interrupted:
        assert output.strip(), f'{command!r} printed nothing before Ctrl-C'
