"""Corrupt bags: seeded random mutations of the sample bags through every `bag` subcommand, in process.

Every run must end in success or in one line on stderr with exit code 2 — never a traceback — and a
run that succeeds on a bag whose MCAP file still reads as properly closed must print exactly what the
intact bag gives (corruption is refused, never turned into made-up figures). Each failing case is
reported with its seed and mutation so it can be replayed:
``python -c "from test_bag_fuzz import replay; replay('avoid', 17)"`` from the test folder.
"""
from __future__ import annotations

import contextlib
import io
import json
import random
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import pytest
from nav_msgs.msg import Odometry
from rclpy.serialization import serialize_message
from std_msgs.msg import String

from epuck_ros.bag_cli import main
from epuck_ros.bag.qos import QosProfile
from epuck_ros.bag.reader import MAX_METADATA_BYTES, Bag
from epuck_ros.bag.writer import BagWriter

SAMPLES = Path(__file__).parent.parent / 'bags'
BIN_DIR = Path(sys.executable).parent
BAGS = sorted(p.name for p in SAMPLES.iterdir() if p.is_dir())
CASES_PER_BAG = 40
LARGE_BAG = 500_000
"""Bytes; bags larger than this (bags/swarm, five robots) get a fifth of the cases: each costs more."""
QUICK_CASES = 8
"""Mutations per bag in `scripts/test.sh`; the others run in its slow tier (`--slow`, which `.ci/run` runs too)."""
PLOT_EVERY = 15
"""Plotting takes ~1 s (matplotlib): one case in this many also plots."""
CSV_TOPICS = ('/odom', '/clock', '/world', '/joint_states', '/no_such_topic')


def mutate_mcap(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    """One random corruption: byte flips, a cut, inserted or deleted bytes; positions favour the file's ends,
    where the header, summary and footer live."""
    def position() -> int:
        where = rng.random()
        if where < 0.25:
            return rng.randrange(min(256, len(data)))
        if where < 0.5:
            return rng.randrange(max(0, len(data) - 4096), len(data))
        return rng.randrange(len(data))

    kind = rng.choice(('flip', 'flip', 'cut', 'insert', 'delete'))
    if kind == 'flip':
        mutated = bytearray(data)
        spots = [position() for _ in range(rng.randint(1, 8))]
        for spot in spots:
            mutated[spot] = rng.randrange(256)
        return bytes(mutated), f'bytes set at {spots}'
    at = position()
    if kind == 'cut':
        return data[:at], f'cut at byte {at}'
    count = rng.randint(1, 64)
    if kind == 'insert':
        return data[:at] + rng.randbytes(count) + data[at:], f'{count} bytes inserted at {at}'
    return data[:at] + data[at + count:], f'{count} bytes deleted at {at}'


def alias_bomb() -> str:
    """A few hundred bytes of YAML whose aliases stand for 10^9 strings."""
    lines = ['a0: &a0 [x, x, x, x, x, x, x, x, x, x]']
    lines += [f'a{i}: &a{i} [{", ".join([f"*a{i - 1}"] * 10)}]' for i in range(1, 9)]
    return '\n'.join(lines) + '\nrosbag2_bagfile_information: {relative_file_paths: *a8}\n'


def mutate_metadata(text: str, rng: random.Random) -> tuple[bytes | None, str]:
    """metadata.yaml replaced by garbage, binary data, an alias bomb, an oversized file, cut, or removed."""
    kind = rng.choice(('binary', 'cut', 'flip', 'aliases', 'huge', 'missing', 'wrong files', 'deep'))
    data = text.encode()
    if kind == 'binary':
        return rng.randbytes(rng.randint(1, 2000)), kind
    if kind == 'cut':
        return data[:rng.randrange(len(data))], kind
    if kind == 'flip':
        mutated = bytearray(data)
        for _ in range(rng.randint(1, 8)):
            mutated[rng.randrange(len(mutated))] = rng.randrange(256)
        return bytes(mutated), kind
    if kind == 'aliases':
        return alias_bomb().encode(), kind
    if kind == 'huge':
        return data + b'#' * (MAX_METADATA_BYTES + 1), kind
    if kind == 'missing':
        return None, kind
    if kind == 'deep':
        return b'rosbag2_bagfile_information: ' + b'[' * 5000 + b']' * 5000 + b'\n', kind
    return text.replace('_0.mcap', '_9.mcap').encode(), kind


def run_bag(*argv: str) -> tuple[int, str, str]:
    """`bag ARGV...` in this process: (exit code, stdout, stderr); a traceback fails the test here."""
    out, err = io.StringIO(), io.StringIO()
    code = 0
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            main(list(argv))
        except SystemExit as stop:
            code = stop.code if isinstance(stop.code, int) else 1
    return code, out.getvalue(), err.getvalue()


def commands(case: int, rng: random.Random, bag: Path, workdir: Path) -> list[list[str]]:
    chosen = [['info', str(bag)], ['summary', str(bag), '--json'],
              ['csv', str(bag), rng.choice(CSV_TOPICS), '-o', str(workdir / 'out.csv')]]
    if case % PLOT_EVERY == 0:
        chosen.append(['plot', str(bag), '-o', str(workdir / 'out.png')])
    return chosen


def make_case(name: str, case: int, workdir: Path) -> tuple[Path, str]:
    """The case's corrupted copy of a sample bag and what was done to it."""
    rng = random.Random(f'{name}-{case}')
    bag = workdir / f'{name}_{case}'
    shutil.rmtree(bag, ignore_errors=True)
    shutil.copytree(SAMPLES / name, bag)
    mcap = bag / f'{name}_0.mcap'
    if rng.random() < 0.8:
        data, what = mutate_mcap(mcap.read_bytes(), rng)
        mcap.write_bytes(data)
    else:
        data, what = mutate_metadata((bag / 'metadata.yaml').read_text(), rng)
        what = f'metadata.yaml: {what}'
        if data is None:
            (bag / 'metadata.yaml').unlink()
        else:
            (bag / 'metadata.yaml').write_bytes(data)
    return bag, what


def check(argv: list[str], code: int, out: str, err: str, intact: dict[str, str]) -> str | None:
    """What is wrong with one run's outcome, or None."""
    if code == 2:
        lines = err.strip().splitlines()
        if len(lines) != 1 or not lines[0].startswith(f'bag {argv[0]}: error: '):
            return f'exit 2 but stderr is not one error line: {err!r}'
        return None
    if code != 0:
        return f'exit code {code}: {err[-500:]!r}'
    if argv[0] == 'summary':
        summaries = json.loads(out)
        summaries = summaries if isinstance(summaries, list) else [summaries]
        expected = json.loads(intact['summary'])
        expected = expected if isinstance(expected, list) else [expected]
        for got, want in zip(summaries, expected):
            got.pop('bag', None)
            want.pop('bag', None)
            if got.get('closed_properly') and got != want:
                return f'figures differ from the intact bag while it reads as closed properly:\n{got}\n{want}'
    return None


@pytest.fixture(scope='module')
def intact_outputs() -> dict[str, dict[str, str]]:
    outputs = {}
    for name in BAGS:
        code, summary, err = run_bag('summary', str(SAMPLES / name), '--json')
        assert code == 0, err
        outputs[name] = {'summary': summary}
    return outputs


@pytest.mark.parametrize('name, first_cases', [(name, True) for name in BAGS] +
                         [pytest.param(name, False, marks=pytest.mark.slow) for name in BAGS])
def test_mutated_sample_bags_end_in_success_or_one_line(name, first_cases, intact_outputs, tmp_path):
    """The first QUICK_CASES mutations of each bag in the default run, the rest in the slow tier."""
    failures, outcomes = [], {0: 0, 2: 0}
    size = sum(f.stat().st_size for f in (SAMPLES / name).iterdir())
    cases = CASES_PER_BAG if size < LARGE_BAG else CASES_PER_BAG // 5
    for case in range(min(cases, QUICK_CASES)) if first_cases else range(QUICK_CASES, cases):
        bag, what = make_case(name, case, tmp_path)
        rng = random.Random(f'{name}-{case}-commands')
        for argv in commands(case, rng, bag, tmp_path):
            try:
                code, out, err = run_bag(*argv)
            except Exception as error:  # noqa: BLE001  the finding itself: a traceback
                failures.append(f'case {case} ({what}): bag {" ".join(argv[:1])} raised {error!r}')
                continue
            outcomes[code] = outcomes.get(code, 0) + 1
            problem = check(argv, code, out, err, intact_outputs[name])
            if problem:
                failures.append(f'case {case} ({what}): bag {argv[0]}: {problem}')
        shutil.rmtree(bag)
    print(f'{name}: {cases} mutations, runs by exit code: {outcomes}')
    assert not failures, '\n'.join(failures)


def replay(name: str, case: int) -> None:
    """Rebuild one case under /tmp and run its commands with tracebacks visible."""
    workdir = Path('/tmp/bag_fuzz_replay')
    workdir.mkdir(exist_ok=True)
    bag, what = make_case(name, case, workdir)
    print(f'{bag}: {what}')
    for argv in commands(case, random.Random(f'{name}-{case}-commands'), bag, workdir):
        print('bag', *argv)
        try:
            main(argv)
        except SystemExit as stop:
            print('exit', stop.code)


# --- targeted corruptions named in the issue --------------------------------------------------------------

def odometry_bytes(x: float) -> bytes:
    message = Odometry(child_frame_id='base_link')
    message.header.frame_id = 'odom'
    message.pose.pose.position.x = x
    message.pose.pose.orientation.w = 1.0
    return serialize_message(message)


def test_an_odometry_message_cut_short_is_refused_not_read_past_its_end(tmp_path):
    """A message record shorter than an Odometry, followed by other records: reading on would take their bytes."""
    writer = BagWriter(tmp_path / 'run')
    writer.add_topic('/odom', 'nav_msgs/msg/Odometry', [QosProfile()])
    writer.add_topic('/chatter', 'std_msgs/msg/String', [QosProfile()])
    for i in range(10):
        writer.write('/odom', odometry_bytes(0.01 * i), i * 10**8)
        writer.write('/chatter', serialize_message(String(data='x' * 600)), i * 10**8 + 1)
    writer.write('/odom', odometry_bytes(0.1)[:40], 10**9)  # header and frame ids only
    for i in range(11, 20):
        writer.write('/chatter', serialize_message(String(data='y' * 600)), i * 10**8)
    writer.close()
    code, out, err = run_bag('summary', str(tmp_path / 'run'))
    assert code == 2 and out == '', out
    assert err.count('\n') == 1 and 'nav_msgs/Odometry: message data ends before the message does' in err


def test_a_binary_metadata_file_is_one_line(tmp_path):
    shutil.copytree(SAMPLES / 'spin', tmp_path / 'spin')
    (tmp_path / 'spin' / 'metadata.yaml').write_bytes(bytes(range(256)) * 4)
    code, _, err = run_bag('info', str(tmp_path / 'spin'))
    assert code == 2 and err.strip().endswith('not a text file (byte 128 is not UTF-8)')


def test_a_huge_metadata_file_is_refused_at_once(tmp_path):
    shutil.copytree(SAMPLES / 'spin', tmp_path / 'spin')
    with open(tmp_path / 'spin' / 'metadata.yaml', 'a') as handle:
        handle.write('# padding\n' * 600_000)  # 6 MB: took 35 s to parse
    code, _, err = run_bag('info', str(tmp_path / 'spin'))
    assert code == 2 and 'too large for a rosbag2 metadata file' in err


def test_a_yaml_alias_bomb_in_metadata_is_refused(tmp_path):
    shutil.copytree(SAMPLES / 'spin', tmp_path / 'spin')
    (tmp_path / 'spin' / 'metadata.yaml').write_text(alias_bomb())
    code, _, err = run_bag('info', str(tmp_path / 'spin'))
    assert code == 2 and 'YAML aliases' in err and 'not allowed' in err


def empty_struct_bomb(path: Path) -> None:
    """A tiny MCAP whose schema has a sequence of an empty struct, and a message claiming 2^32 - 1 of them."""
    from mcap.writer import Writer
    with open(path, 'wb') as stream:
        writer = Writer(stream)
        writer.start(profile='ros2', library='fuzz')
        schema = writer.register_schema('pkg/msg/Bomb', 'ros2msg',
                                        b'Empty[] items\n' + b'=' * 80 + b'\nMSG: pkg/Empty\n')
        channel = writer.register_channel('/bomb', 'cdr', schema)
        writer.add_message(channel, 1, b'\x00\x01\x00\x00' + struct.pack('<I', 2**32 - 1), 1)
        writer.finish()


def test_a_sequence_of_empty_structs_cannot_allocate_gigabytes(tmp_path):
    empty_struct_bomb(tmp_path / 'bomb.mcap')
    assert (tmp_path / 'bomb.mcap').stat().st_size < 1024
    code, out, err = run_bag('csv', str(tmp_path / 'bomb.mcap'), '/bomb')
    assert code == 2 and 'pkg/Bomb: message data ends before the message does' in err


def test_a_world_alias_bomb_inside_a_bag_costs_nothing(tmp_path):
    """The `world` topic holds YAML whose aliases stand for 10^9 values: the world is refused (summary goes on
    without it); under a 2 GB address-space limit a loader that expands it fails instead of swapping."""
    shutil.copytree(SAMPLES / 'spin', tmp_path / 'spin')
    writer = BagWriter(tmp_path / 'bomb')
    with Bag(tmp_path / 'spin') as sample:
        for name, topic in sample.topics.items():
            writer.add_topic(name, topic.type_name, [QosProfile()])
        for message in sample.messages():
            data = message.data
            if message.topic == '/world':
                data = serialize_message(String(data=alias_bomb().replace('rosbag2_bagfile_information', 'arena')))
            writer.write(message.topic, data, message.log_time)
    writer.close()
    command = f'ulimit -v 2000000; exec "{BIN_DIR / "bag"}" summary "{tmp_path / "bomb"}"'
    result = subprocess.run(['bash', '-c', command], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert 'world not used' in result.stdout and 'aliases' in result.stdout


def test_deeply_nested_schema_types_are_refused(tmp_path):
    """2,000 message types each holding the next: a recursive check would end in RecursionError."""
    from mcap.writer import Writer
    blocks = ['Level1 next\n'] + [f'MSG: pkg/Level{i}\nLevel{i + 1} next\n' for i in range(1, 2000)]
    blocks.append('MSG: pkg/Level2000\nuint8 value\n')
    with open(tmp_path / 'deep.mcap', 'wb') as stream:
        writer = Writer(stream)
        writer.start(profile='ros2', library='fuzz')
        schema = writer.register_schema('pkg/msg/Deep', 'ros2msg', ('=' * 80 + '\n').join(blocks).encode())
        writer.add_message(writer.register_channel('/deep', 'cdr', schema), 1, b'\x00\x01\x00\x00\x07', 1)
        writer.finish()
    code, _, err = run_bag('csv', str(tmp_path / 'deep.mcap'), '/deep')
    assert code == 2 and 'types nested more than 64 levels deep' in err


def test_a_zstd_chunk_of_zeros_cannot_become_gigabytes_of_values(tmp_path):
    """A few KB of zstd inflate to 50 MB of zeros: read as one uint8[] that would be 50 million Python ints
    (about 2 GB)."""
    from mcap.writer import CompressionType, Writer
    with open(tmp_path / 'zeros.mcap', 'wb') as stream:
        writer = Writer(stream, compression=CompressionType.ZSTD, chunk_size=100 * 2**20)
        writer.start(profile='ros2', library='fuzz')
        schema = writer.register_schema('pkg/msg/Blob', 'ros2msg', b'uint8[] data\n')
        size = 50 * 2**20
        writer.add_message(writer.register_channel('/blob', 'cdr', schema), 1,
                           b'\x00\x01\x00\x00' + struct.pack('<I', size) + bytes(size), 1)
        writer.finish()
    assert (tmp_path / 'zeros.mcap').stat().st_size < 100_000
    code, _, err = run_bag('csv', str(tmp_path / 'zeros.mcap'), '/blob', '-o', str(tmp_path / 'blob.csv'))
    assert code == 2 and 'more than 4,000,000 array elements in one message' in err
