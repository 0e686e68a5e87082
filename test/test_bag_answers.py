"""`bag info`, `record` and `bringup`'s summary check a lockstep controller's answers against the steps (issue 33,
item 8): a `wheel_cmd` answer missing from a bag is reported, not "Stamp gaps: none". The bag is a headless trial's
(`webots_controller --headless --record`, the bytes of a recorded run), copied without some of its answers."""
from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
from conftest import BIN_DIR

from epuck_ros.bag.gaps import answer_gaps, bag_gaps
from epuck_ros.bag.info import format_info
from epuck_ros.bag.reader import Bag
from epuck_ros.bag.writer import BagWriter
from epuck_ros.bringup.run import recording_losses

SCRIPT = Path(__file__).resolve().parents[1] / 'epuck_ros' / 'webots' / 'examples' / 'straight_line.py'


@pytest.fixture(scope='module')
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Path:
    bag = tmp_path_factory.mktemp('answers') / 'whole'
    made = subprocess.run([str(BIN_DIR / 'webots_controller'), str(SCRIPT), '--headless', '--duration', '2',
                           '--record', str(bag)], capture_output=True, text=True, timeout=120)
    assert made.returncode == 0, made.stdout + made.stderr
    return bag


def copy_without(source: Path, target: Path, topic: str, drop: set[int],
                 replace: dict[str, bytes] | None = None) -> None:
    """`source` copied to `target` without the messages of `topic` at indexes `drop`, and with the messages of the
    topics in `replace` replaced by those bytes."""
    replace = replace or {}
    writer = BagWriter(target)
    with Bag(source) as bag:
        index = 0
        for message in bag.messages():
            if message.topic not in writer.topics:
                writer.add_topic(message.topic, bag.topics[message.topic].type_name, [])
            if message.topic == topic:
                index += 1
                if index - 1 in drop:
                    continue
            writer.write(message.topic, replace.get(message.topic, message.data), message.log_time,
                         message.publish_time)
    writer.close()


def test_every_answer_there_is_no_gap(recorded):
    with Bag(recorded) as bag:
        checked, found = answer_gaps(bag)
        info = format_info(bag)
    assert checked == ['/wheel_cmd'] and found == []
    assert 'Stamp gaps:        none in the' in info, info
    assert recording_losses(recorded) == []


def test_missing_answers_are_listed_by_bag_info_and_the_bringup_summary(recorded, tmp_path):
    lossy = tmp_path / 'lossy'
    copy_without(recorded, lossy, '/wheel_cmd', {5, 6, 40})
    with Bag(lossy) as bag:
        _, found = bag_gaps(bag)
        info = format_info(bag)
    (answers,) = [gaps for gaps in found if gaps.topic == '/wheel_cmd']
    assert answers.missing == 3 and answers.first_missing_ns == 6 * 32_000_000
    assert '/wheel_cmd: 3 of 62 steps have no answer naming them (first at t=0.192 s)' in info, info
    assert 'none in the' not in info
    assert recording_losses(lossy) == [answers.describe()]


def test_answers_are_checked_only_while_the_run_was_lockstep(recorded, tmp_path):
    """A run that stopped being reproducible at t=0.1 s (a controller at its own rate skips steps: nothing is lost)
    is checked up to then only."""
    from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

    from epuck_ros.integrity import Integrity
    from epuck_ros.ros.serialized import exact_cdr
    level, name, message, values = Integrity(False, 'a controller at its own rate', 0.1).fields()
    status = DiagnosticStatus(level=bytes([level]), name=name, message=message,
                              values=[KeyValue(key=key, value=value) for key, value in values])
    broken = tmp_path / 'broken'
    copy_without(recorded, broken, '/wheel_cmd', {5, 6, 40}, {'/lockstep_status': exact_cdr(status)})
    with Bag(broken) as bag:
        assert answer_gaps(bag) == (['/wheel_cmd'], [])
    copy_without(recorded, tmp_path / 'early', '/wheel_cmd', {1}, {'/lockstep_status': exact_cdr(status)})
    with Bag(tmp_path / 'early') as bag:
        assert [gaps.missing for gaps in answer_gaps(bag)[1]] == [1]
