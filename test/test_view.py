"""The view without ROS: the state it draws, the actions it accepts, and its HTTP server over a real socket."""
from __future__ import annotations

import http.client
import json
import math
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import yaml

from epuck_ros.model import SENSOR_NAMES
from epuck_ros.swarm_messages import OBSERVATION_FIELDS, OBSERVATION_TOPIC, SwarmLayout, SwarmReader
from epuck_ros.view.follow import CAMERA_TOPIC, DETAIL_TOPICS, LATCHED_TOPICS, STEP_TOPICS, SWARM, wanted_topics

from epuck_ros.view.server import ACTIONS, MAX_POLLED, MAX_STREAMS, Action, ActionError, ViewServer, parse_action
from epuck_ros.view.state import ViewState, robot_topic
from epuck_ros.world import Box, RobotStart, World, load_world, world_from_yaml

WORLDS = Path(__file__).resolve().parents[1] / 'epuck_ros' / 'worlds'

THREE = World(arena_size=(1.5, 1.0), boxes=(Box(0.4, 0.3, 0.1, 0.1),),
              robots=(RobotStart('epuck0', -0.3, 0.0, 0.0), RobotStart('epuck1', 0.1, 0.2, math.pi / 2),
                      RobotStart('epuck2', 0.3, -0.3, 0.0)))


# --- state ---------------------------------------------------------------------------------------------------

def test_topics_are_prefixed_only_when_there_are_several_robots() -> None:
    assert robot_topic(('epuck',), 'epuck', 'ground_truth') == 'ground_truth'
    assert robot_topic(THREE.names, 'epuck1', 'ground_truth') == 'epuck1/ground_truth'


def test_frame_holds_every_robot_and_the_odometry_error_in_the_world_frame() -> None:
    state = ViewState()
    state.set_world(THREE)
    state.set_detailed(frozenset({'epuck1'}))
    # epuck1 starts at (0.1, 0.2) facing +y: 0.1 m forward in its odom frame is (0.1, 0.3) in the world.
    state.update('epuck1', pose=(0.1, 0.31, math.pi / 2 + 0.05), stamp=1.5, odom=(0.1, 0.0, 0.0),
                 wheel_speeds=(1.0, 2.0), collisions=2)
    state.update('nobody', pose=(0.0, 0.0, 0.0))  # not in the world: ignored
    frame = json.loads(state.frame_json(wall_now=0.0))
    assert sorted(frame['robots']) == ['epuck0', 'epuck1', 'epuck2']
    robot = frame['robots']['epuck1']
    assert robot['pose'] == [0.1, 0.31, pytest.approx(math.pi / 2 + 0.05)]
    assert robot['stamp'] == 1.5 and robot['wheel_speeds'] == [1.0, 2.0]
    assert robot['odom_error']['odom_in_world'] == pytest.approx([0.1, 0.3])
    assert robot['odom_error']['distance'] == pytest.approx(0.01)
    assert robot['odom_error']['yaw'] == pytest.approx(-0.05)
    assert frame['collisions'] is None   # not every robot's count is known
    assert frame['robots']['epuck0']['pose'] is None
    # The robots not shown in detail: only what the canvas draws.
    assert sorted(frame['robots']['epuck0']) == ['collisions', 'ir_range', 'ir_raw', 'leds', 'pose', 'stamp']
    state.update('epuck0', collisions=1)
    state.update('epuck2', collisions=0)
    assert json.loads(state.frame_json(wall_now=0.0))['collisions'] == 3


def test_a_swarm_observation_sets_every_robot_it_names_and_the_time() -> None:
    state = ViewState()
    state.set_world(THREE)
    table = state.model.ir_table
    rows = np.zeros((2, len(OBSERVATION_FIELDS)))
    for row, (x, raw) in enumerate(((0.25, table[3, 1]), (-0.5, table[-1, 1]))):
        values = {'truth_x': x, 'truth_y': 0.125, 'truth_yaw': 1.0, 'odom_x': 0.5, 'wheel_left_speed': 2.0,
                  **{f'{sensor}_raw': raw for sensor in SENSOR_NAMES}}
        for field, value in values.items():
            rows[row, OBSERVATION_FIELDS.index(field)] = value
    data = SwarmLayout(('epuck2', 'epuck0'), OBSERVATION_FIELDS).to_bytes(rows, (3, 200_000_000))
    state.set_swarm(SwarmReader().read(data), wall_time=10.0)
    assert state.time == pytest.approx(3.2)
    epuck2, epuck0 = state.robots['epuck2'], state.robots['epuck0']
    assert epuck2.pose == (0.25, 0.125, 1.0) and epuck0.pose == (-0.5, 0.125, 1.0)
    assert epuck2.odom == (0.5, 0.0, 0.0) and epuck2.wheel_speeds == (2.0, 0.0)
    assert epuck2.ir_range == [pytest.approx(table[3, 0])] * 8 and epuck0.ir_range == [state.model.ir_range] * 8
    assert epuck2.stamp == pytest.approx(3.2) and state.robots['epuck1'].pose is None   # not in the message


def test_a_swarm_observation_of_non_finite_numbers_still_gives_json_the_page_parses() -> None:
    """Any node on the domain may publish on swarm/observation."""
    state = ViewState()
    state.set_world(THREE)
    rows = np.full((3, len(OBSERVATION_FIELDS)), np.nan)
    rows[1] = np.inf
    state.set_swarm(SwarmReader().read(SwarmLayout(THREE.names, OBSERVATION_FIELDS).to_bytes(rows, (1, 0))), 0.0)

    def strict(constant: str) -> None:
        raise ValueError(f'{constant} is not JSON')
    frame = json.loads(state.frame_json(wall_now=0.0), parse_constant=strict)
    assert frame['robots']['epuck0']['pose'] == [None] * 3 and frame['robots']['epuck1']['pose'] == [None] * 3


def test_the_view_reads_a_swarm_in_one_message_and_own_topics_only_of_robots_in_detail() -> None:
    robots = tuple(f'epuck{i}' for i in range(300))
    assert wanted_topics(robots, False, {'epuck7'}, True, robots, (), False) == set()   # no page: nothing
    swarm = wanted_topics(robots, True, {'epuck7', 'nobody'}, True, (), (), False)
    assert swarm == {(SWARM, OBSERVATION_TOPIC), ('epuck7', CAMERA_TOPIC), ('epuck7', 'collisions'),
                     ('epuck7', 'leds')}
    few = wanted_topics(robots[:3], True, {'epuck1'}, True, robots[:3], (), True)   # the latched ones of all
    assert {topic for topic in few if topic[1] in LATCHED_TOPICS} == {
        (robot, topic) for robot in robots[:3] for topic in LATCHED_TOPICS}
    # No swarm topic (one robot, a bag without it): the own step topics of the robots that publish them.
    own = wanted_topics(('epuck0', 'epuck1'), True, {'epuck1'}, False, {'epuck0'}, {'epuck0'}, True)
    assert {topic for topic in own if topic[1] in (*STEP_TOPICS, *DETAIL_TOPICS)} == {
        ('epuck0', 'ground_truth'), ('epuck0', 'ir_raw'), ('epuck1', 'odom'), ('epuck1', 'joint_states')}


def test_ir_readings_become_ray_lengths_through_the_lookup_table() -> None:
    state = ViewState()
    table = state.model.ir_table
    state.set_world(World())
    state.set_ir_raw('epuck', [float(table[0, 1]), float(table[3, 1]), float(table[-1, 1]), 10.0] + [0.0] * 4)
    ranges = state.robots['epuck'].ir_range
    assert ranges[:3] == pytest.approx([0.0, table[3, 0], table[-1, 0]])
    assert ranges[3] == state.model.ir_range  # beyond the table's far end: drawn full length, no further
    # A Range message of a bag without ir_raw: inf is nothing seen, drawn full length with the far raw value.
    state.set_ir_range('epuck', 5, math.inf)
    state.set_ir_range('epuck', 6, 0.02)
    assert state.robots['epuck'].ir_range[5:7] == [state.model.ir_range, 0.02]
    assert state.robots['epuck'].ir_raw[5:7] == pytest.approx([table[-1, 1], table[4, 1]])


def test_real_time_factor_is_measured_over_the_last_second_and_falls_to_zero_when_time_stands_still() -> None:
    state = ViewState()
    for i in range(11):
        state.set_time(sim_time=0.2 * i, wall_time=100.0 + 0.1 * i)
    assert state.real_time_factor(wall_now=101.0) == pytest.approx(2.0)
    assert state.real_time_factor(wall_now=103.0) == 0.0
    state.set_time(sim_time=0.0, wall_time=103.0)  # time went back (a bag replayed): old samples dropped
    state.set_time(sim_time=0.5, wall_time=103.5)
    assert state.real_time_factor(wall_now=103.5) == pytest.approx(1.0)


def test_world_json_carries_what_the_page_draws() -> None:
    state = ViewState()
    state.set_world(THREE)
    world = json.loads(state.world_json())
    assert world['arena'] == [1.5, 1.0]
    assert world['boxes'] == [{'x': 0.4, 'y': 0.3, 'size_x': 0.1, 'size_y': 0.1, 'yaw': 0.0,
                               'color': [0.72, 0.53, 0.33]}]   # the default box colour
    assert (world['floor'], world['lights'], world['wall_color']) == (None, [], None)   # plain: the page's own
    assert [r['name'] for r in world['robots']] == ['epuck0', 'epuck1', 'epuck2']
    assert world['robots'][1]['start'] == [0.1, 0.2, pytest.approx(math.pi / 2)]
    assert len(world['model']['sensor_poses']) == 8


def _as_the_view_node_reads_it(name: str) -> World:
    """A shipped world as the view gets it: the YAML the sim publishes on `world`, read back."""
    world = load_world(WORLDS / name)
    return world_from_yaml(yaml.safe_dump(world.to_dict(), sort_keys=False), source='world topic')


def test_world_json_carries_the_floor_paint_lights_and_colours_of_the_shipped_worlds() -> None:
    state = ViewState()
    state.set_world(_as_the_view_node_reads_it('line_track.yaml'))
    track = json.loads(state.world_json())
    assert track['floor']['color'] == [1.0, 1.0, 1.0]
    [line] = track['floor']['paint']
    assert (line['kind'], line['width'], line['color']) == ('polyline', 0.025, [0.0, 0.0, 0.0])
    assert line['points'][0] == [0.0, -0.25] and len(line['points']) == 33
    state.set_world(_as_the_view_node_reads_it('lit_arena.yaml'))
    lit = json.loads(state.world_json())
    assert lit['lights'] == [{'x': 0.25, 'y': 0.25, 'z': 0.07, 'intensity': 0.5}]
    assert lit['floor']['paint'] == [{'kind': 'disc', 'points': [[0.25, 0.25]], 'color': [1.0, 0.85, 0.2],
                                      'width': 0.0, 'radius': 0.06}]
    assert lit['boxes'][0]['color'] == [0.2, 0.3, 0.8]
    state.set_world(_as_the_view_node_reads_it('coloured_objects.yaml'))
    coloured = json.loads(state.world_json())
    assert [b['color'] for b in coloured['boxes']] == [[0.9, 0.1, 0.1], [0.1, 0.7, 0.2]]
    assert [c['color'] for c in coloured['cylinders']] == [[0.15, 0.25, 0.9]]
    assert coloured['wall_color'] == [0.8, 0.8, 0.8]


# --- actions -------------------------------------------------------------------------------------------------

def test_the_page_can_ask_only_for_the_whitelisted_actions() -> None:
    assert set(ACTIONS) == {'pause', 'step', 'reset', 'real_time_factor', 'drive'}
    assert parse_action('/api/pause', b'{"paused": true}') == Action('pause', {'paused': True})
    assert parse_action('/api/step', b'') == Action('step', {})
    assert parse_action('/api/real_time_factor', b'{"value": 0}') == Action('real_time_factor', {'value': 0.0})
    assert parse_action('/api/drive', b'{"robot": "epuck1", "linear": 0.1, "angular": -1}') == \
        Action('drive', {'robot': 'epuck1', 'linear': 0.1, 'angular': -1.0})


@pytest.mark.parametrize('path, body, complaint', [
    ('/api/shutdown', b'{}', 'unknown action'),
    ('/api/../api/step', b'{}', 'unknown action'),
    ('/api/pause', b'{"paused": "yes"}', 'paused'),
    ('/api/pause', b'[true]', 'JSON object'),
    ('/api/pause', b'\xff', 'not JSON'),
    ('/api/step', b'{"count": 3}', 'unexpected'),
    ('/api/real_time_factor', b'{"value": NaN}', 'finite'),
    ('/api/real_time_factor', b'{"value": -1}', 'outside'),
    ('/api/real_time_factor', b'{"value": true}', 'finite number'),
    ('/api/drive', b'{"robot": "epuck", "linear": 1e308, "angular": 0}', 'outside'),
    ('/api/drive', b'{"robot": 3, "linear": 0, "angular": 0}', 'robot'),
    ('/api/drive', b'{"robot": "epuck", "linear": 0, "angular": 0, "topic": "/x"}', 'robot'),
])
def test_bad_actions_are_refused_with_a_reason(path: str, body: bytes, complaint: str) -> None:
    with pytest.raises(ActionError, match=complaint):
        parse_action(path, body)


# --- the server over HTTP ------------------------------------------------------------------------------------

class Recorder:
    """An ActionHandler that keeps what it was asked and refuses driving an unknown robot."""

    def __init__(self) -> None:
        self.actions: list[Action] = []

    def __call__(self, action: Action) -> dict:
        if action.name == 'drive' and action.args['robot'] != 'epuck':
            raise ActionError('no such robot')
        self.actions.append(action)
        return {'done': action.name}


@pytest.fixture
def served() -> Iterator[tuple[ViewServer, ViewState, Recorder]]:
    state, recorder = ViewState(), Recorder()
    server = ViewServer('127.0.0.1', 0, state, recorder)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield server, state, recorder
    server.close()
    thread.join(timeout=10)


def _request(server: ViewServer, method: str, path: str, body: bytes | None = None,
             headers: dict | None = None) -> tuple[int, bytes, str]:
    connection = http.client.HTTPConnection(*server.server_address[:2], timeout=10)
    connection.request(method, path, body=body, headers=headers or {})
    response = connection.getresponse()
    result = response.status, response.read(), response.getheader('Content-Type', '')
    connection.close()
    return result


JSON = {'Content-Type': 'application/json'}


def test_the_page_and_its_assets_are_served_from_the_package(served) -> None:
    server = served[0]
    status, body, kind = _request(server, 'GET', '/')
    assert status == 200 and kind.startswith('text/html') and b'/static/view.js' in body
    for asset, expected_kind in (('view.js', 'text/javascript'), ('view.css', 'text/css')):
        status, body, kind = _request(server, 'GET', f'/static/{asset}')
        assert status == 200 and kind.startswith(expected_kind) and body
    assert b'http' not in _request(server, 'GET', '/static/view.js')[1].replace(b'http.', b'')  # no CDN
    for path in ('/static/../server.py', '/static/%2e%2e/server.py', '/static/missing.js', '/nothing'):
        assert _request(server, 'GET', path)[0] == 404


def test_actions_reach_the_handler_only_from_this_page(served) -> None:
    server, _, recorder = served
    body = b'{"paused": true}'
    status, answer, _ = _request(server, 'POST', '/api/pause', body, JSON)
    assert status == 200 and json.loads(answer) == {'done': 'pause'}
    assert recorder.actions == [Action('pause', {'paused': True})]
    refused = [
        _request(server, 'POST', '/api/pause', body, {'Content-Type': 'text/plain'}),   # a cross-site form
        _request(server, 'POST', '/api/pause', body, {**JSON, 'Origin': 'http://evil.example'}),
        _request(server, 'POST', '/api/pause', body, {**JSON, 'Host': 'evil.example:8765'}),  # DNS rebinding
    ]
    assert [status for status, _, _ in refused] == [403, 403, 403]
    status, answer, _ = _request(server, 'POST', '/api/drive', b'{"robot": "x", "linear": 0, "angular": 0}', JSON)
    assert status == 400 and json.loads(answer) == {'error': 'no such robot'}
    assert _request(server, 'POST', '/api/pause', b'{"paused": 1}', JSON)[0] == 400
    assert _request(server, 'POST', '/api/step', b' ' * 5000, JSON)[0] == 400
    assert len(recorder.actions) == 1


def test_pages_and_polls_say_which_robots_are_watched(served) -> None:
    server = served[0]
    assert server.watched() == set()
    _request(server, 'GET', '/state?robot=epuck2')
    assert server.watched() == {'epuck2'}
    connection = http.client.HTTPConnection(*server.server_address[:2], timeout=10)
    connection.request('GET', '/events?robot=epuck0')
    response = connection.getresponse()
    next(_events(response))
    assert 'epuck0' in server.watched()
    response.close()
    connection.close()
    deadline = time.monotonic() + 30
    while 'epuck0' in server.watched() and time.monotonic() < deadline:
        server.state.set_time(time.monotonic(), time.monotonic())  # the stream writes, and finds the page gone
        time.sleep(0.05)
    assert 'epuck0' not in server.watched()


def _events(response: http.client.HTTPResponse) -> Iterator[tuple[str, dict]]:
    kind = None
    for raw in response:
        line = raw.decode().rstrip('\n')
        if line.startswith('event: '):
            kind = line[len('event: '):]
        elif line.startswith('data: '):
            yield kind, json.loads(line[len('data: '):])


def test_the_event_stream_sends_the_world_then_the_newest_state(served) -> None:
    server, state, _ = served
    state.set_world(THREE)
    connection = http.client.HTTPConnection(*server.server_address[:2], timeout=10)
    connection.request('GET', '/events')
    response = connection.getresponse()
    assert response.getheader('Content-Type') == 'text/event-stream'
    events = _events(response)
    kind, world = next(events)
    assert kind == 'world' and [r['name'] for r in world['robots']] == ['epuck0', 'epuck1', 'epuck2']
    for i in range(1, 501):  # far faster than the stream's frame rate: the page gets the newest, not each one
        state.update('epuck2', pose=(0.001 * i, 0.0, 0.0), stamp=0.032 * i)
    for kind, frame in events:
        assert kind == 'state'
        if frame['robots']['epuck2']['stamp'] == pytest.approx(0.032 * 500):
            break
    assert frame['robots']['epuck2']['pose'] == [0.5, 0.0, 0.0]
    state.set_world(World())  # a new world reaches a connected page
    assert next(kind for kind, _ in events if kind == 'world') == 'world'
    connection.close()


def test_hostile_requests_get_an_answer_and_cost_bounded_memory(served) -> None:
    """Each of these once got no answer and a traceback, or kept memory for ever."""
    server, state, recorder = served
    for body in (b'[' * 2000 + b']' * 2000, b'{"linear": 1' + b'0' * 400 + b', "angular": 0, "robot": "epuck"}',
                 b'{"factor": 1e400}', b'{"paused": ' + b'1' * 5000 + b'}'):
        status, answer, _ = _request(server, 'POST', '/api/drive', body, JSON)
        assert status == 400 and 'error' in json.loads(answer), body[:40]
    status, _, _ = _request(server, 'POST', '/api/pause', b'{}', {**JSON, 'Content-Length': '9' * 5000})
    assert status == 400
    for i in range(3000):   # made-up robot names, before the world is known: at most MAX_POLLED remembered
        _request(server, 'GET', f'/state?robot=r{i}')
    assert len(server._polls) <= MAX_POLLED
    state.set_world(THREE)
    _request(server, 'GET', '/state?robot=nobody')
    assert 'nobody' not in server.watched()
    assert recorder.actions == []


def test_every_request_from_a_foreign_host_is_refused(served) -> None:
    """GET had no Host check: a DNS-rebinding page could read /state, /world and /events."""
    server = served[0]
    for path in ('/', '/state', '/world', '/events', '/static/view.js'):
        status, answer, _ = _request(server, 'GET', path, headers={'Host': 'rebound.example:8765'})
        assert status == 403 and b'is not this machine' in answer, path
    assert _request(server, 'GET', '/state', headers={'Host': f'localhost:{server.server_address[1]}'})[0] == 200


def test_a_nan_pose_still_gives_json_the_page_parses(served) -> None:
    server, state, _ = served
    state.set_world(THREE)
    state.update('epuck1', pose=(math.nan, math.inf, 0.0), stamp=0.032)

    def strict(constant: str) -> None:
        raise ValueError(f'{constant} is not JSON')
    frame = json.loads(_request(server, 'GET', '/state')[1], parse_constant=strict)
    assert frame['robots']['epuck1']['pose'][:2] == [None, None]


def test_event_streams_are_capped(served) -> None:
    server = served[0]
    connections = []
    try:
        for _ in range(MAX_STREAMS):
            connection = http.client.HTTPConnection(*server.server_address[:2], timeout=10)
            connection.request('GET', '/events')
            response = connection.getresponse()
            assert response.status == 200
            next(_events(response))
            connections.append(connection)
        status, answer, _ = _request(server, 'GET', '/events')
        assert status == 503 and f'{MAX_STREAMS} pages are open already'.encode() in answer
    finally:
        for connection in connections:
            connection.close()
