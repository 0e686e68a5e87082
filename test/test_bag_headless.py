"""A headless trial's bag is the bag `bringup --record` writes of the same run: every topic with its type, offered
QoS and messages (frames and stamps included), compared topic by topic, decoded by rosbags (an independent reader).

The runs are lockstep runs of the same world, seed and duration: a behaviour on three robots through `sweep --record`
against `bringup avoid --robots 3`, and a Webots script that reads a sense and sets its LEDs through `webots_controller
--headless --record` against `bringup --controller`. What a run over ROS has beyond the run itself is left out by
name (ROS_ONLY), and so are, in the bag over ROS, what may or may not arrive before the recording stops (the answer
to the last step) and the copies of a first step the simulator sent again (`compare`)."""
from __future__ import annotations

import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from conftest import BIN_DIR
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from epuck_ros.conversions import stamp_from_label

REPO = Path(__file__).resolve().parents[1]
LEDS_EVERY_STEP = REPO / 'test' / 'data' / 'webots' / 'leds_every_step.py'
ROS_ONLY = {'/rosout', '/parameter_events', '/simulators'}
"""Topics of a run over ROS that are not the run: the processes' log lines, bringup's resume and pause (parameter
events), the simulators' announcements."""
TYPES = get_typestore(Stores.ROS2_JAZZY)


def read(bag: Path) -> dict[str, dict[str, Any]]:
    """Per topic: its type, its offered QoS profiles (metadata.yaml) and its messages decoded by rosbags."""
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    topics = {entry['topic_metadata']['name']: {'type': entry['topic_metadata']['type'],
                                                'qos': entry['topic_metadata']['offered_qos_profiles'],
                                                'messages': []}
              for entry in info['topics_with_message_count']}
    with AnyReader([bag], default_typestore=TYPES) as reader:
        for connection, _, data in reader.messages():
            topics[connection.topic]['messages'].append(reader.deserialize(data, connection.msgtype))
    return topics


def plain(value: Any) -> Any:
    """A decoded message as nested tuples of plain values (arrays as lists), comparable with ==."""
    if hasattr(value, '__dataclass_fields__'):
        return tuple((name, plain(getattr(value, name))) for name in value.__dataclass_fields__
                     if name != '__msgtype__')
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (list, tuple)):
        return [plain(item) for item in value]
    return value


def step_of(msg: Any) -> tuple[int, int] | None:
    """The step a labelled array names (None: it names none)."""
    dims = msg.layout.dim   # a robot's array: one dimension; a swarm's: the stamp's first (epuck_ros/swarm_messages.py)
    return stamp_from_label(dims[0].label) if dims else None


FIRST_STEP = (0, 32_000_000)


def step_named(msg: Any) -> tuple[int, int] | None:
    """The step a message belongs to (its header's stamp, a Clock's, a TFMessage's, a labelled array's); None for
    one that names no step (a latched world, a contact count)."""
    for stamp in (getattr(getattr(msg, 'header', None), 'stamp', None), getattr(msg, 'clock', None),
                  msg.transforms[0].header.stamp if getattr(msg, 'transforms', None) else None):
        if stamp is not None:
            return stamp.sec, stamp.nanosec
    return step_of(msg) if hasattr(msg, 'layout') else None


def without_first_step_again(messages: list[Any]) -> list[Any]:
    """The messages but those of the first step sent again: the simulator sends its first step again to a controller
    that has not answered it within a second (lockstep.RESEND_AFTER, a loaded machine starting a script), and a
    recorder takes the copies too."""
    kept, first = [], []
    for msg in messages:
        if step_named(msg) == FIRST_STEP:
            value = plain(msg)
            if value in first:
                continue
            first.append(value)
        kept.append(msg)
    return kept


def compare(ros: dict[str, dict[str, Any]], headless: dict[str, dict[str, Any]], last_step: tuple[int, int]) -> None:
    """Every topic of the run in both bags, with the same type, offered QoS and messages (the arrays' layouts, which
    name their steps, included). Over ROS the answer to the last step (it drives nothing) and the LEDs a script set
    while handling it may come before the recorder stops, or not: one such message more is left out; so are the
    copies of the first step the simulator sent again."""
    assert set(ros) - ROS_ONLY == set(headless), sorted((set(ros) - ROS_ONLY) ^ set(headless))
    for topic, mine in headless.items():
        theirs = ros[topic]
        assert mine['type'] == theirs['type'], topic
        assert mine['qos'] == theirs['qos'], (topic, mine['qos'], theirs['qos'])
        expected = [plain(msg) for msg in mine['messages']]
        ros_messages = without_first_step_again(theirs['messages'])
        found = [plain(msg) for msg in ros_messages]
        if topic.endswith(('/wheel_cmd', '/leds', '/swarm/command')) and len(found) == len(expected) + 1:
            extra = next((index for index in reversed(range(len(found)))
                          if found[:index] + found[index + 1:] == expected), None)
            assert extra is not None and extra >= len(found) - 2, (topic, extra)   # last, or before a behaviour's stop
            assert not topic.endswith(('/wheel_cmd', '/swarm/command')) or \
                step_of(ros_messages[extra]) in (None, last_step)
            del found[extra]
        assert found == expected, (topic, len(found), len(expected),
                                   next((i for i, (a, b) in enumerate(zip(found, expected)) if a != b), None))


def run_both(folder: Path, bringup: list[str], headless: list[str]) -> Path:
    """Run `bringup ... --record` (its bag: returned) and the `headless` command (it records a bag of its own)."""
    ros = folder / 'ros'
    over_ros = subprocess.run([str(BIN_DIR / 'bringup'), *bringup, '--lockstep', '--real-time-factor', '0',
                               '--record', str(ros)], capture_output=True, text=True, timeout=300)
    assert over_ros.returncode == 0, over_ros.stdout + over_ros.stderr
    made = subprocess.run([str(BIN_DIR / headless[0]), *headless[1:]], capture_output=True, text=True, timeout=300)
    assert made.returncode == 0, made.stdout + made.stderr
    return ros


@pytest.fixture(scope='module')
def avoid_bags(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict, dict]:
    """The behaviour `avoid` on three robots (seed 3, 6 s): `bringup avoid --robots 3` and a sweep of that one trial,
    recorded."""
    folder = tmp_path_factory.mktemp('avoid')
    spec = folder / 'spec.yaml'
    spec.write_text(yaml.safe_dump({'controllers': ['avoid'], 'worlds': ['default'], 'robots': [3], 'seeds': [3],
                                    'duration': 6, 'noise': True}))
    ros = run_both(folder, ['avoid', '--robots', '3', '--seed', '3', '--duration', '6'],
                   ['sweep', str(spec), '-o', str(folder / 'sweep'), '--workers', '0', '--record'])
    return read(ros), read(folder / 'sweep' / 'bags' / '0')


@pytest.fixture(scope='module')
def script_bags(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict, dict]:
    """A script that reads its ground sensors, sets its LEDs every step and drives into a wall (seed 5, 6 s):
    `bringup --controller` and `webots_controller --headless --record`."""
    folder = tmp_path_factory.mktemp('script')
    options = ['--seed', '5', '--duration', '6']
    ros = run_both(folder, ['--controller', str(LEDS_EVERY_STEP), *options],
                   ['webots_controller', str(LEDS_EVERY_STEP), '--headless', *options, '--record',
                    str(folder / 'headless')])
    return read(ros), read(folder / 'headless')


LAST_STEP = (6, 16_000_000)
"""Both runs end on the first step at or after 6 s: 188 steps of 32 ms."""


def test_a_sweeps_bag_is_the_bringup_bag_of_the_same_run(avoid_bags):
    """Three robots' topics under their names, TF, robot descriptions, contacts, and the swarm topics of the one
    `avoid --robots all` that drives them (its declaration, then a command naming each step), as over ROS."""
    ros, headless = avoid_bags
    assert {'/tf', '/tf_static', '/epuck2/robot_description', '/swarm/command', '/swarm/observation',
            '/epuck0/ir_raw', '/lockstep_status'} <= set(headless)
    declaration, first = headless['/swarm/command']['messages'][:2]
    assert (step_of(declaration), list(declaration.data)) == (None, [])
    assert step_of(first) == (0, 32_000_000)
    compare(ros, headless, LAST_STEP)


def test_a_headless_scripts_bag_is_the_bringup_bag_of_the_same_run(script_bags):
    """The sense the script read (from the step it asked for it on), its LEDs and its contact with the wall too, as
    over ROS."""
    ros, headless = script_bags
    assert {'/ground_raw', '/leds', '/wheel_cmd', '/tf'} <= set(headless)
    assert step_of(headless['/ground_raw']['messages'][0]) == (0, 32_000_000)
    assert [msg.data for msg in headless['/collisions']['messages']] == [0, 1]
    compare(ros, headless, LAST_STEP)
