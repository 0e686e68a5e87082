"""The swarm messages (nodes/swarm_messages.py) as bytes, and the lockstep declaration they carry: no DDS here."""
from __future__ import annotations

import time

import numpy as np
import pytest

from epuck_ros import lockstep
from epuck_ros.lockstep import Answer, Lockstep
from epuck_ros.nodes.serialized import _TYPESTORE
from epuck_ros.nodes.swarm_messages import COMMAND_FIELDS, OBSERVATION_FIELDS, SwarmLayout, SwarmReader

FLOAT64_ARRAY = 'std_msgs/msg/Float64MultiArray'


@pytest.mark.parametrize('stamp', [(12, 32000000), (0, 0), None])
@pytest.mark.parametrize('fields', [COMMAND_FIELDS, OBSERVATION_FIELDS, ()])
@pytest.mark.parametrize('robots', [['epuck0'], ['a', 'bb', 'epuck10']])
def test_a_swarm_message_is_a_float64_multi_array_as_rosbags_writes_it(stamp, fields, robots):
    """Byte for byte what rosbags (and Fast DDS, zero padding) make of the same message, so bags, `ros2 topic echo`
    and Foxglove read it; and read back by `SwarmReader`."""
    data = np.arange(len(robots) * len(fields), dtype=float).reshape(len(robots), len(fields)) * 1.5 - 2.0
    raw = SwarmLayout(robots, fields).to_bytes(data, stamp)
    msg = _TYPESTORE.deserialize_cdr(raw, FLOAT64_ARRAY)
    assert bytes(_TYPESTORE.serialize_cdr(msg, FLOAT64_ARRAY)) == raw
    labels = [dim.label for dim in msg.layout.dim]
    assert labels[-2:] == ['robots=' + ','.join(robots), 'fields=' + ','.join(fields)]
    assert labels[:-2] == ([] if stamp is None else [f'stamp={stamp[0]}.{stamp[1]:09d}'])
    assert (msg.data == data.ravel()).all()
    read = SwarmReader().read(raw)
    assert (read.stamp, read.robots, read.fields) == (stamp, tuple(robots), tuple(fields))
    assert (read.data == data).all()


def test_bytes_that_are_no_swarm_message_are_none_not_an_error():
    good = SwarmLayout(['epuck0', 'epuck1'], COMMAND_FIELDS).to_bytes(np.ones((2, 2)), (1, 0))
    reader = SwarmReader()
    wrong_sizes = SwarmLayout(['epuck0'], COMMAND_FIELDS).to_bytes(np.ones((1, 2)), (1, 0)).replace(
        b'robots=epuck0', b'robots=epuckX,y')
    for bad in [b'', b'\x00\x01\x00\x00', good[:-8], good[:40], b'\x01' * 200, good.replace(b'stamp=1.', b'stamp=x.'),
                wrong_sizes, _TYPESTORE.serialize_cdr(_TYPESTORE.types[FLOAT64_ARRAY](
                    layout=_TYPESTORE.types['std_msgs/msg/MultiArrayLayout'](dim=[], data_offset=0),
                    data=np.ones(3)), FLOAT64_ARRAY)]:
        assert reader.read(bytes(bad)) is None
    assert reader.read(good).robots == ('epuck0', 'epuck1')


def test_a_declared_controller_is_waited_for_however_long_its_first_answer_takes(monkeypatch):
    """Two robots whose controllers never answered: the undeclared one is taken for free after FIRST_ANSWER_WAIT
    (a wall-clock rule), the declared one (a swarm controller said it answers by name) is waited for: the step is
    re-sent, never passed without it, until it answers."""
    monkeypatch.setattr(lockstep, 'FIRST_ANSWER_WAIT', 0.05)
    monkeypatch.setattr(lockstep, 'RESEND_AFTER', 0.01)
    steps, freed = [], []
    sync = Lockstep(2, lambda resend: steps.append(resend), on_free=lambda robot, why: freed.append((robot, why)))
    sync.claim()
    sync.declare([0])
    sync.step()
    deadline = time.monotonic() + 60.0
    while not freed and time.monotonic() < deadline:
        assert not sync.await_answers()   # re-sent: robot 0 has not answered
        sync.step(resend=True)
    assert freed == [(1, Answer.SILENT)]
    started = time.monotonic()
    while time.monotonic() - started < 0.2:   # four times FIRST_ANSWER_WAIT more: still waited for
        assert not sync.await_answers()
        sync.step(resend=True)
    assert freed == [(1, Answer.SILENT)]
    sync.answer(0, Answer.STEP, 32_000_000)
    assert sync.await_answers()   # answered: the step is done (the free robot 1 waited for OWN_RATE_WAIT at most)
