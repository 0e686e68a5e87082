"""A headless trial's bag is the bag `bringup --record` writes of the same run: every topic with its type, offered
QoS and messages (frames and stamps included), compared topic by topic, decoded by rosbags (an independent reader).

The runs are lockstep runs of the same world, seed and duration: a behaviour on three robots through `sweep --record`
against `bringup avoid --robots 3`, and a Webots script that reads a sense and sets its LEDs through `webots_controller
--headless --record` against `bringup --controller`, each over ROS twice: once alone, once beside a busy loop on every
core. Every message that names a step is logged at that step in all of them (issue 33, item 10: log times once
followed the recorder's clock, -2.4 to +3.0 s off under load, and the last step's answer was in one bag and not in
the other). What a run over ROS has beyond the run itself is left out by name (ROS_ONLY), and so are the LEDs a
script set while handling the last step, which may reach the recorder before it stops, or not (`compare`)."""
from __future__ import annotations

import os
import subprocess
import sys
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
ROS_ONLY = {'/rosout', '/parameter_events', '/simulators', '/lockstep_declarations'}
"""Topics of a run over ROS that are not the run: the processes' log lines, bringup's resume and pause (parameter
events), the simulators' announcements, the controllers' lockstep declarations (how the processes tell the
simulator what to wait for; in one process there is nothing to tell)."""
TYPES = get_typestore(Stores.ROS2_JAZZY)


def read(bag: Path) -> dict[str, dict[str, Any]]:
    """Per topic: its type, its offered QoS profiles (metadata.yaml), its messages decoded by rosbags and their log
    times (file order)."""
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    topics = {entry['topic_metadata']['name']: {'type': entry['topic_metadata']['type'],
                                                'qos': entry['topic_metadata']['offered_qos_profiles'],
                                                'messages': [], 'log_times': []}
              for entry in info['topics_with_message_count']}
    with AnyReader([bag], default_typestore=TYPES) as reader:
        for connection, log_time, data in reader.messages():
            topics[connection.topic]['messages'].append(reader.deserialize(data, connection.msgtype))
            topics[connection.topic]['log_times'].append(log_time)
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


def step_named(msg: Any) -> tuple[int, int] | None:
    """The step a message belongs to (its header's stamp, a Clock's, a TFMessage's, a labelled array's); None for
    one that names no step (a latched world, a contact count)."""
    for stamp in (getattr(getattr(msg, 'header', None), 'stamp', None), getattr(msg, 'clock', None),
                  msg.transforms[0].header.stamp if getattr(msg, 'transforms', None) else None):
        if stamp is not None:
            return stamp.sec, stamp.nanosec
    return step_of(msg) if hasattr(msg, 'layout') else None


def steps_and_messages(topic: dict[str, Any]) -> list[tuple[int | None, Any]]:
    """A topic's messages in the bag's order as (log time, message) for those that name a step, (None, message) for
    the others (logged at the recorder's clock over ROS)."""
    pairs = []
    for log_time, msg in zip(topic['log_times'], topic['messages']):
        step = step_named(msg)
        step = None if step == (0, 0) else step   # before the run (/tf_static): logged at the first step
        if step is not None:
            assert log_time == step[0] * 1_000_000_000 + step[1], (log_time, step)   # logged at the step it names
        pairs.append((log_time if step is not None else None, plain(msg)))
    return pairs


def compare(ros: dict[str, dict[str, Any]], headless: dict[str, dict[str, Any]]) -> None:
    """Every topic of the run in both bags, with the same type, offered QoS, messages (the arrays' layouts, which
    name their steps, included) and, for each message that names a step, the same log time: that step. Over ROS the
    LEDs a script set while handling the last step may come before the recorder stops, or not: one such message
    more, the last, is left out. The messages that name a step are compared in order; those that name none (a
    swarm controller's declaration, the LEDs) in their own order: over ROS such a message is logged at the
    recorder's clock, so where it falls among the step messages of its topic depends on when it arrived (a swarm
    controller's declaration, sent before its first answer, was written after that answer in 2 of 6 loaded runs)."""
    assert set(ros) - ROS_ONLY == set(headless), sorted((set(ros) - ROS_ONLY) ^ set(headless))
    for topic, mine in headless.items():
        theirs = ros[topic]
        assert mine['type'] == theirs['type'], topic
        assert mine['qos'] == theirs['qos'], (topic, mine['qos'], theirs['qos'])
        expected, found = steps_and_messages(mine), steps_and_messages(theirs)
        if topic.endswith('/leds') and len(found) == len(expected) + 1:
            del found[-1]
        for named in (True, False):
            these, those = ([pair for pair in pairs if (pair[0] is not None) is named] for pairs in (found, expected))
            assert these == those, (topic, named, len(these), len(those),
                                    next((i for i, (a, b) in enumerate(zip(these, those)) if a != b), None))


def run_both(folder: Path, bringup: list[str], headless: list[str]) -> tuple[Path, Path]:
    """Run `bringup ... --record` twice, alone and beside a busy loop on every core (their bags: returned), and the
    `headless` command (it records a bag of its own)."""
    bags = folder / 'quiet', folder / 'loaded'
    for bag in bags:
        loops = [subprocess.Popen([sys.executable, '-c', 'while True: pass']) for _ in range(os.cpu_count() or 1)
                 ] if bag.name == 'loaded' else []
        try:
            over_ros = subprocess.run([str(BIN_DIR / 'bringup'), *bringup, '--lockstep', '--real-time-factor', '0',
                                       '--record', str(bag)], capture_output=True, text=True, timeout=600)
        finally:
            for loop in loops:
                loop.kill()
                loop.wait()
        assert over_ros.returncode == 0, over_ros.stdout + over_ros.stderr
    made = subprocess.run([str(BIN_DIR / headless[0]), *headless[1:]], capture_output=True, text=True, timeout=300)
    assert made.returncode == 0, made.stdout + made.stderr
    return bags


@pytest.fixture(scope='module')
def avoid_bags(tmp_path_factory: pytest.TempPathFactory) -> tuple[list[dict], dict]:
    """The behaviour `avoid` on three robots (seed 3, 6 s): `bringup avoid --robots 3` and a sweep of that one trial,
    recorded."""
    folder = tmp_path_factory.mktemp('avoid')
    spec = folder / 'spec.yaml'
    spec.write_text(yaml.safe_dump({'controllers': ['avoid'], 'worlds': ['default'], 'robots': [3], 'seeds': [3],
                                    'duration': 6, 'noise': True}))
    ros = run_both(folder, ['avoid', '--robots', '3', '--seed', '3', '--duration', '6'],
                   ['sweep', str(spec), '-o', str(folder / 'sweep'), '--workers', '0', '--record'])
    return [read(bag) for bag in ros], read(folder / 'sweep' / 'bags' / '0')


@pytest.fixture(scope='module')
def script_bags(tmp_path_factory: pytest.TempPathFactory) -> tuple[list[dict], dict]:
    """A script that reads its ground sensors, sets its LEDs every step and drives into a wall (seed 5, 6 s):
    `bringup --controller` and `webots_controller --headless --record`."""
    folder = tmp_path_factory.mktemp('script')
    options = ['--seed', '5', '--duration', '6']
    ros = run_both(folder, ['--controller', str(LEDS_EVERY_STEP), *options],
                   ['webots_controller', str(LEDS_EVERY_STEP), '--headless', *options, '--record',
                    str(folder / 'headless')])
    return [read(bag) for bag in ros], read(folder / 'headless')


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
    assert LAST_STEP not in {step_of(msg) for msg in headless['/swarm/command']['messages']}
    for bag in ros:
        compare(bag, headless)


def test_a_headless_scripts_bag_is_the_bringup_bag_of_the_same_run(script_bags):
    """The sense the script read (from the step it asked for it on), its LEDs and its contact with the wall too, as
    over ROS."""
    ros, headless = script_bags
    assert {'/ground_raw', '/leds', '/wheel_cmd', '/tf'} <= set(headless)
    assert step_of(headless['/ground_raw']['messages'][0]) == (0, 32_000_000)
    assert [msg.data for msg in headless['/collisions']['messages']] == [0, 1]
    for bag in ros:
        compare(bag, headless)
