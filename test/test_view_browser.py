"""The view in a real browser (headless Chromium through Selenium and the system chromedriver) while a real sim runs.

The simulator starts paused and moves only when the page's Step button is clicked (or, once, when it is resumed),
so what the page draws is compared with `ground_truth` at the same simulated instant, never by timing.
"""
from __future__ import annotations

import math
import os
import re
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from rclpy._rclpy_pybind11 import NodeNameNonExistentError
from rclpy.parameter_client import AsyncParameterClient
from std_msgs.msg import Float64MultiArray

from epuck_ros.swarm_messages import OBSERVATION_FIELDS, OBSERVATION_TOPIC, SwarmReader

CHROMIUM = shutil.which('chromium') or '/usr/bin/chromium'
CHROMEDRIVER = shutil.which('chromedriver') or '/usr/bin/chromedriver'
if not (Path(CHROMIUM).exists() and Path(CHROMEDRIVER).exists()):
    pytest.skip('Chromium is not installed (apt-get install chromium chromium-driver; .ci/run does): '
                'the browser tests of the view are skipped', allow_module_level=True)

from selenium import webdriver  # noqa: E402
from selenium.webdriver.chrome.service import Service  # noqa: E402
from selenium.webdriver.common.action_chains import ActionChains  # noqa: E402
from selenium.webdriver.common.by import By  # noqa: E402
from selenium.webdriver.common.keys import Keys  # noqa: E402
from selenium.webdriver.support.select import Select  # noqa: E402
from selenium.webdriver.support.ui import WebDriverWait  # noqa: E402

STEP = 0.032
TIMEOUT = 60.0
README_SCREENSHOT = Path(__file__).resolve().parents[1] / 'docs' / 'images' / 'view.png'
"""Rewritten only when EPUCK_ROS_UPDATE_SCREENSHOT=1: a test run must not change tracked files."""
THREE_ROBOTS = """
arena: {size: [1.0, 0.8]}
boxes: [{position: [-0.3, 0.2], size: [0.1, 0.1], yaw: 0.4, color: [0.85, 0.2, 0.15]}]
cylinders: [{position: [0.25, -0.2], radius: 0.05, color: [0.2, 0.35, 0.85]}]
floor:
  color: [0.96, 0.96, 0.93]
  paint:
    - {polyline: [[-0.45, -0.25], [-0.1, -0.25], [0.1, -0.05], [0.4, -0.05]], width: 0.02, color: [0.1, 0.1, 0.1]}
    - {disc: [0.3, 0.25], radius: 0.06, color: [1.0, 0.85, 0.2]}
lights: [{position: [0.3, 0.25, 0.07], intensity: 0.5}]
robots:
  - {name: epuck0, start: [-0.3, -0.34, 0.0]}
  - {name: epuck1, start: [0.0, 0.1, 1.5708]}
  - {name: epuck2, start: [0.31, -0.09, 3.1416]}
"""


@pytest.fixture(scope='module')
def browser() -> Iterator[webdriver.Chrome]:
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    profile = tempfile.mkdtemp(prefix='epuck_view_chromium_')
    for argument in ('--headless=new', '--no-sandbox', '--disable-gpu', '--disable-background-networking',
                     '--disable-component-update', '--disable-sync', '--no-first-run', '--window-size=1200,760',
                     f'--user-data-dir={profile}'):
        options.add_argument(argument)
    driver = webdriver.Chrome(options=options, service=Service(CHROMEDRIVER))
    try:
        yield driver
    finally:
        driver.quit()  # ends chromedriver and every Chromium process it started
        shutil.rmtree(profile, ignore_errors=True)


def _yaw(msg: Odometry) -> float:
    q = msg.pose.pose.orientation
    return 2.0 * math.atan2(q.z, q.w)


class Truth:
    """Every ground_truth message of one robot, by stamp (ns)."""

    def __init__(self, test_node, topic: str) -> None:
        self.poses: dict[int, tuple[float, float, float]] = {}
        test_node.node.create_subscription(Odometry, topic, self._on_msg, 1000)

    def _on_msg(self, msg: Odometry) -> None:
        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        self.poses[stamp] = (msg.pose.pose.position.x, msg.pose.pose.position.y, _yaw(msg))


def _ns(seconds: float) -> int:
    return round(seconds * 1e9)


class Page:
    """The view's page in the browser: clicks, keys, and what it last drew (`window.epuckView.drawn`)."""

    def __init__(self, driver: webdriver.Chrome, url: str) -> None:
        self.driver = driver
        driver.get(url)
        self.wait_until(lambda: self.script('return view.world && view.world.robots && view.frame '
                                            '&& view.frame.paused !== null'),
                        'the page to show the world and the simulator settings')

    def script(self, code: str) -> object:
        return self.driver.execute_script(code.replace('view.', 'window.epuckView.'))

    def wait_until(self, condition, what: str) -> object:
        return WebDriverWait(self.driver, TIMEOUT, poll_frequency=0.05).until(
            lambda _: condition(), message=f'waiting for {what}')

    def drawn(self) -> dict:
        return self.script('return view.drawn') or {}

    def click(self, element_id: str) -> None:
        self.driver.find_element(By.ID, element_id).click()

    def text(self, element_id: str) -> str:
        return self.driver.find_element(By.ID, element_id).text

    def step(self) -> float:
        """Click Step; the simulated time of that step, as the simulator answered it (shown on the page)."""
        self.script("document.getElementById('message').textContent = ''")
        self.click('step')
        message = self.wait_until(lambda: self.text('message').startswith('step: t=') and self.text('message'),
                                  'the answer to Step')
        stepped = float(message.split('t=')[1].split()[0])
        self.wait_until(lambda: self.drawn().get('time') == pytest.approx(stepped, abs=1e-9),
                        f'the page to draw t={stepped}')
        return stepped


def _step_until_heard(page: Page, test_node, truths: list[Truth]) -> float:
    """Step until the test node hears a step's ground_truth: before its subscriptions have matched the sim's
    publishers (which nothing outside DDS tells), a step's messages may pass it by. Returns that step's time."""
    for _ in range(20):
        stepped = page.step()
        test_node.spin_for(0.2)
        if all(_ns(stepped) in truth.poses for truth in truths):
            return stepped
    raise AssertionError('the test node heard no ground_truth of 20 steps')


def _open_view(launch, *sim_params: str) -> str:
    launch('sim', '--ros-args', '-p', 'paused:=true', '-p', 'noise:=false', *sim_params)
    view = launch('view', '--ros-args', '-p', 'port:=0')
    view.wait_for_output('view: http://')
    return next(line for line in view.output().splitlines() if line.startswith('view: '))[len('view: '):]


def _settings(test_node, client: AsyncParameterClient) -> dict:
    future = client.get_parameters(['paused', 'real_time_factor'])
    test_node.spin_until(future.done, what='the simulator parameters', timeout=60)
    values = future.result().values
    return {'paused': values[0].bool_value, 'real_time_factor': values[1].double_value}


def test_page_draws_ground_truth_steps_pauses_and_drives(launch, test_node, browser) -> None:
    truth = Truth(test_node, 'ground_truth')
    commands = test_node.collect(Twist, 'cmd_vel', 1000)
    sim_parameters = AsyncParameterClient(test_node.node, 'sim')
    page = Page(browser, _open_view(launch))
    assert page.text('run-state') == 'paused'

    # Paused: a Step is exactly one time step, and the robot is drawn where ground_truth says.
    first = _step_until_heard(page, test_node, [truth])
    assert page.step() == pytest.approx(first + STEP, abs=1e-9)
    test_node.spin_until(lambda: _ns(first + STEP) in truth.poses, what='ground_truth of the second step', timeout=60)
    drawn = page.drawn()['robots']['epuck']
    assert _ns(drawn['stamp']) == _ns(first + STEP)
    assert drawn['pose'] == pytest.approx(truth.poses[_ns(first + STEP)], abs=1e-12)

    # A held arrow key drives the robot: cmd_vel from the page, then the next steps move it forward.
    page.click('arena')
    ActionChains(browser).key_down(Keys.ARROW_UP).perform()
    test_node.spin_until(lambda: commands and commands[-1].linear.x > 0.0,
                         what='a forward cmd_vel from the page', timeout=60)
    assert commands[-1].angular.z == 0.0
    start_x = truth.poses[_ns(first + STEP)][0]
    for _ in range(5):  # the command reaches the sim with the page's next message at the latest
        stepped = page.step()
        test_node.spin_until(lambda: _ns(stepped) in truth.poses, what='ground_truth of the step', timeout=60)
        if truth.poses[_ns(stepped)][0] > start_x:
            break
    moved = truth.poses[_ns(stepped)]
    assert moved[0] > start_x and moved[1] == pytest.approx(0.0, abs=1e-9)
    assert page.drawn()['robots']['epuck']['pose'] == pytest.approx(moved, abs=1e-12)
    ActionChains(browser).key_up(Keys.ARROW_UP).perform()
    test_node.spin_until(lambda: commands[-1].linear.x == 0.0 and commands[-1].angular.z == 0.0,
                         what='the stop sent when the key is released', timeout=60)

    # Real-time factor, resume and pause go to the simulator's parameters.
    rtf_input = browser.find_element(By.ID, 'rtf-input')
    rtf_input.clear()
    rtf_input.send_keys('0')
    page.click('rtf-set')
    test_node.spin_until(lambda: _settings(test_node, sim_parameters)['real_time_factor'] == 0.0,
                         what='real_time_factor 0 on the sim', timeout=60)
    page.click('pause')  # labelled Resume while paused
    page.wait_until(lambda: (page.drawn().get('time') or 0.0) > stepped + 1.0, 'simulated time to run on')
    assert not _settings(test_node, sim_parameters)['paused']
    page.wait_until(lambda: page.text('pause') == 'Pause', 'the button to offer Pause')
    page.click('pause')
    test_node.spin_until(lambda: _settings(test_node, sim_parameters)['paused'], what='paused on the sim', timeout=60)
    page.wait_until(lambda: page.text('run-state') == 'paused', 'the page to show paused')
    # Paused at a real-time factor of 0: time stands still, two Steps are exactly one step apart.
    after_pause = page.step()
    assert page.step() == pytest.approx(after_pause + STEP, abs=1e-9)


def test_several_robots_each_drawn_and_only_the_selected_one_driven(launch, test_node, browser, tmp_path) -> None:
    world = tmp_path / 'three.yaml'
    world.write_text(THREE_ROBOTS)
    names = ('epuck0', 'epuck1', 'epuck2')
    truths = {name: Truth(test_node, f'{name}/ground_truth') for name in names}
    commands = {name: test_node.collect(Twist, f'{name}/cmd_vel', 1000) for name in names}
    page = Page(browser, _open_view(launch, '-p', f'world:={world}'))
    assert page.script('return view.world.robots.map(r => r.name)') == list(names)

    Select(browser.find_element(By.ID, 'robot')).select_by_value('epuck1')
    _step_until_heard(page, test_node, list(truths.values()))
    page.click('arena')
    ActionChains(browser).key_down(Keys.ARROW_UP).key_down(Keys.ARROW_LEFT).perform()
    test_node.spin_until(lambda: commands['epuck1'] and commands['epuck1'][-1].linear.x > 0.0
                         and commands['epuck1'][-1].angular.z > 0.0, what='an arc cmd_vel for epuck1', timeout=60)
    for _ in range(5):
        stepped = page.step()
        test_node.spin_until(lambda: all(_ns(stepped) in truths[n].poses for n in names),
                             what='every ground_truth', timeout=60)
        if truths['epuck1'].poses[_ns(stepped)][1] > 0.1:
            break
    assert truths['epuck1'].poses[_ns(stepped)][1] > 0.1  # epuck1 faces +y: forward is up
    drawn = page.drawn()['robots']
    for name in names:
        assert drawn[name]['pose'] == pytest.approx(truths[name].poses[_ns(stepped)], abs=1e-12)
    assert truths['epuck0'].poses[_ns(stepped)] == pytest.approx((-0.3, -0.34, 0.0), abs=1e-9)
    assert commands['epuck0'] == [] and commands['epuck2'] == []

    # For the README: let the selected robot drive an arc for two simulated seconds, then take the picture.
    page.click('pause')
    page.wait_until(lambda: (page.drawn().get('time') or 0.0) > stepped + 2.0, 'two simulated seconds')
    page.click('pause')
    page.wait_until(lambda: page.text('run-state') == 'paused', 'the page to show paused')
    screenshot = README_SCREENSHOT if os.environ.get('EPUCK_ROS_UPDATE_SCREENSHOT') == '1' else tmp_path / 'view.png'
    assert browser.save_screenshot(str(screenshot)) and screenshot.stat().st_size > 0
    ActionChains(browser).key_up(Keys.ARROW_UP).key_up(Keys.ARROW_LEFT).perform()


def _canvas_pixel(page: Page, x: float, y: float) -> list[int]:
    """The RGBA the canvas shows at world point (x, y) m, through the page's own world-to-canvas transform."""
    return page.script(f'const t = worldTransform();'
                       f'const px = Math.round(t.cx + t.scale * {x}), py = Math.round(t.cy - t.scale * {y});'
                       f'return Array.from(canvas.getContext("2d").getImageData(px, py, 1, 1).data);')


def test_the_floor_paint_of_the_line_track_is_drawn(launch, browser) -> None:
    """The world the sim publishes reaches the canvas with its floor: a pixel on the track's black line is black,
    one in the middle of the oval is the floor's white."""
    world = Path(__file__).resolve().parents[1] / 'epuck_ros' / 'worlds' / 'line_track.yaml'
    page = Page(browser, _open_view(launch, '-p', f'world:={world}'))
    page.wait_until(lambda: page.script('return view.drawn && view.drawn.world === view.world.version'),
                    'the page to draw the world')
    assert _canvas_pixel(page, 0.35, 0.0) == [0, 0, 0, 255]          # a vertex of the oval, on the line
    assert _canvas_pixel(page, 0.0, 0.0) == [255, 255, 255, 255]     # the white floor inside it


SWARM_ROBOTS = 200
"""From this many robots (`ros.on_demand.TOPICS_ON_DEMAND_FROM`) the simulator makes a robot's topics only once
someone reads them: the graph shows what the view reads."""


class SwarmTruth:
    """Every robot's ground truth of each step, by stamp (ns), from the test's own reader of `swarm/observation`."""

    def __init__(self, test_node) -> None:
        self.poses: dict[int, dict[str, tuple[float, float, float]]] = {}
        self._reader = SwarmReader()
        test_node.node.create_subscription(Float64MultiArray, OBSERVATION_TOPIC, self._on_msg, 1000, raw=True)

    def _on_msg(self, data: bytes) -> None:
        step = self._reader.read(data)
        truth = [OBSERVATION_FIELDS.index(field) for field in ('truth_x', 'truth_y', 'truth_yaw')]
        self.poses[step.stamp[0] * 10**9 + step.stamp[1]] = {
            robot: tuple(row) for robot, row in zip(step.robots, step.data[:, truth].tolist())}


def test_a_swarm_is_drawn_whole_from_one_topic_and_only_the_selected_robot_is_read_by_its_own(
        launch, test_node, browser, tmp_path) -> None:
    """200 robots: the page draws every robot where the simulator has it, and the view reads every robot's step
    from swarm/observation: of the robots' own topics, only the selected robot's are in the graph (the simulator
    makes them on demand), besides epuck3's ground truth the test reads itself to tie the two together."""
    world = tmp_path / 'arena5.yaml'
    world.write_text('arena: {size: [5.0, 5.0]}\n')
    swarm, epuck3 = SwarmTruth(test_node), Truth(test_node, 'epuck3/ground_truth')
    # The address names the robot shown in detail: the page reads no other robot's own topics, even at first.
    page = Page(browser, _open_view(launch, '-p', f'world:={world}', '-p', f'robots:={SWARM_ROBOTS}') + '?robot=epuck7')
    assert browser.find_element(By.ID, 'robot').get_attribute('value') == 'epuck7'
    stepped = _step_until_heard(page, test_node, [swarm, epuck3])
    page.wait_until(lambda: len(page.drawn()['robots']) == SWARM_ROBOTS, 'every robot drawn')
    drawn = page.drawn()['robots']
    truth = swarm.poses[_ns(stepped)]
    assert {name: tuple(robot['pose']) for name, robot in drawn.items()} == truth
    assert truth['epuck3'] == pytest.approx(epuck3.poses[_ns(stepped)], abs=1e-12)
    page.wait_until(lambda: page.text('pose') != '–', "the selected robot's pose shown")
    assert float(page.text('pose').split(' m')[0]) == pytest.approx(truth['epuck7'][0], abs=6e-4)

    def view_reads() -> set[str]:
        try:
            return {topic for topic, _ in test_node.node.get_subscriber_names_and_types_by_node('view', '/')}
        except NodeNameNonExistentError:   # the test's node has not discovered the view yet
            return set()
    test_node.spin_until(lambda: {f'/{OBSERVATION_TOPIC}', '/epuck7/camera/image_raw'} <= view_reads(),
                         what='the view to read the swarm topic and the selected camera', timeout=60)
    assert {topic for topic in view_reads() if re.match(r'/epuck\d+/', topic)} == {
        '/epuck7/camera/image_raw', '/epuck7/collisions', '/epuck7/leds'}
    robots_in_graph = {name.split('/')[1] for name, _ in test_node.node.get_topic_names_and_types()
                       if re.match(r'/epuck\d+/', name) and name != '/epuck3/ground_truth'}
    assert robots_in_graph == {'epuck7'}
