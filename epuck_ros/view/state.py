"""What the page draws, without ROS: the world, each robot's newest readings, simulated time and its rate.

The view node writes into a `ViewState` from its callbacks; the HTTP server reads JSON frames from it. A frame
is built once per change and shared by every connected page, so the cost of encoding does not grow with the
number of browsers; the server sends at most `MAX_FRAME_RATE` of them a second. A swarm's step arrives as one
`swarm/observation` message (`set_swarm`: every robot in one go); a frame carries everything only of the robots a page
shows in detail, of the others what the canvas draws (`RobotReadings.drawn_json`), so its size grows slowly with
the robots.
"""
from __future__ import annotations

import json
import math
import threading
from collections import deque
from dataclasses import asdict, dataclass, field

import numpy as np

from epuck_ros import ir_sensor
from epuck_ros.model import LED_COLORS, LED_POSITIONS, RobotModel
from epuck_ros.swarm_messages import OBSERVATION_FIELDS, SwarmArray
from epuck_ros.world import World
from epuck_ros.world.appearance import FLOOR_COLOR, WALL_COLOR

RTF_WINDOW = 1.0
"""Wall seconds of simulated-time samples over which the real-time factor reached is measured."""
_SWARM_COLUMNS = {name: [OBSERVATION_FIELDS.index(field) for field in fields] for name, fields in {
    'pose': ('truth_x', 'truth_y', 'truth_yaw'), 'odom': ('odom_x', 'odom_y', 'odom_yaw'),
    'wheel_speeds': ('wheel_left_speed', 'wheel_right_speed'),
    'ir_raw': tuple(f for f in OBSERVATION_FIELDS if f.endswith('_raw'))}.items()}
"""The swarm observation's columns of what the view keeps of each robot."""


def page_json(value: object) -> str:
    """JSON the page's JSON.parse accepts: NaN and infinities (a NaN pose from any node on the domain, or a replayed
    bag) become null instead of the bare NaN Python writes. Looked for only when there is one: a swarm's frame is
    thousands of numbers, and the walk took longer than the encoding."""
    try:
        return json.dumps(value, allow_nan=False)
    except ValueError:
        return json.dumps(_finite(value), allow_nan=False)


def _finite(value: object) -> object:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {key: _finite(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(item) for item in value]
    return value


def robot_topic(robot_names: tuple[str, ...], robot: str, topic: str) -> str:
    """A robot's topic as the simulator names it: `topic` when it simulates one robot, `<robot>/topic` otherwise."""
    return topic if len(robot_names) == 1 else f'{robot}/{topic}'


@dataclass
class RobotReadings:
    """The newest of everything the view knows about one robot; None until the first message."""

    pose: tuple[float, float, float] | None = None
    """Ground truth (x, y, yaw) in the world frame."""
    stamp: float | None = None
    """Simulated time (s) of that ground truth."""
    odom: tuple[float, float, float] | None = None
    """Odometry (x, y, yaw) in the robot's odom frame, which is its start pose."""
    ir_raw: list[float] | None = None
    ir_range: list[float] | None = None
    """Distance (m) each ray is drawn to: the inverse lookup table, clipped to [0, ir_range]."""
    wheel_speeds: tuple[float, float] | None = None
    collisions: int | None = None
    """Contacts so far (`collisions`); None while the view does not follow the robot's count."""
    leds: list[int] | None = None
    """led0..led9 as the robot's controller set them (`leds`)."""
    camera: float | None = None
    """Simulated time (s) of the newest camera image (shown for the robot a page looks at)."""

    def to_json(self, start: tuple[float, float, float]) -> dict:
        """Everything, for a robot a page shows in detail."""
        return {'pose': self.pose, 'stamp': self.stamp, 'odom': self.odom,
                'odom_error': _odom_error(start, self.odom, self.pose),
                'ir_raw': self.ir_raw, 'ir_range': self.ir_range, 'wheel_speeds': self.wheel_speeds,
                'collisions': self.collisions, 'leds': self.leds, 'camera': self.camera}

    def drawn_json(self) -> dict:
        """What the canvas draws of a robot not shown in detail: a swarm's frame is mostly these (the raw IR values
        only colour the rays: a tenth is more than a colour tells)."""
        return {'pose': self.pose, 'stamp': self.stamp,
                'ir_raw': None if self.ir_raw is None else [round(v, 1) for v in self.ir_raw],
                'ir_range': self.ir_range, 'collisions': self.collisions, 'leds': self.leds}


def _odom_error(start: tuple[float, float, float], odom: tuple[float, float, float] | None,
                truth: tuple[float, float, float] | None) -> dict | None:
    """The gap between odometry (taken into the world frame through the start pose) and the true pose."""
    if odom is None or truth is None:
        return None
    sx, sy, syaw = start
    ox, oy, oyaw = odom
    x = sx + math.cos(syaw) * ox - math.sin(syaw) * oy
    y = sy + math.sin(syaw) * ox + math.cos(syaw) * oy
    yaw_error = math.remainder(syaw + oyaw - truth[2], math.tau)
    return {'distance': math.hypot(x - truth[0], y - truth[1]), 'yaw': yaw_error, 'odom_in_world': (x, y)}


def _world_body(world: World) -> dict:
    """What the page draws of a world, from the world's own appearance (as `bag plot` draws it): obstacles and walls
    in their colours, the floor's colour and paint (None when plain and default: the page keeps its own floor), the
    lights. Paint items keep the world's order (later ones are painted over earlier ones)."""
    looks = world.appearance
    plain = not looks.paint and looks.floor_color == FLOOR_COLOR
    return {
        'arena': list(world.arena_size),
        'wall_color': None if looks.wall_color == WALL_COLOR else list(looks.wall_color),
        'boxes': [{'x': b.x, 'y': b.y, 'size_x': b.size_x, 'size_y': b.size_y, 'yaw': b.yaw,
                   'color': list(looks.box_color(i))} for i, b in enumerate(world.boxes)],
        'cylinders': [{'x': c.x, 'y': c.y, 'radius': c.radius, 'color': list(looks.cylinder_color(i))}
                      for i, c in enumerate(world.cylinders)],
        'floor': None if plain else {'color': list(looks.floor_color), 'paint': [asdict(p) for p in looks.paint]},
        'lights': [asdict(light) for light in looks.lights],
        'robots': [{'name': r.name, 'start': [r.x, r.y, r.yaw]} for r in world.robots]}


@dataclass
class SimSettings:
    """The simulator's parameters the page shows and changes; None until read from the simulator."""

    paused: bool | None = None
    real_time_factor: float | None = None


@dataclass
class ViewState:
    """Thread-safe store of the newest data; `version` counts changes so readers send only what is new."""

    model: RobotModel = field(default_factory=RobotModel)
    world: World | None = None
    robots: dict[str, RobotReadings] = field(default_factory=dict)
    time: float | None = None
    settings: SimSettings = field(default_factory=SimSettings)
    version: int = 0
    world_version: int = 0
    detailed: frozenset[str] = frozenset()
    """The robots some page shows in detail: their frame entries carry everything (`RobotReadings.to_json`)."""
    _clock_samples: deque = field(default_factory=lambda: deque(maxlen=512))
    _lock: threading.Condition = field(default_factory=threading.Condition)
    _frame_cache: tuple[int, float, str] | None = None
    _camera_png: dict[str, bytes] = field(default_factory=dict)

    def _changed(self) -> None:
        self.version += 1
        self._lock.notify_all()

    def set_world(self, world: World) -> None:
        """A new world: its robots replace the old ones (readings start afresh)."""
        with self._lock:
            self.world = world
            self.robots = {start.name: RobotReadings() for start in world.robots}
            self.world_version += 1
            self._changed()

    @property
    def robot_names(self) -> tuple[str, ...]:
        with self._lock:
            return tuple(self.robots)

    def set_time(self, sim_time: float, wall_time: float) -> None:
        """The simulated time of what is drawn, seen at `wall_time` (monotonic s)."""
        with self._lock:
            if self.time is not None and sim_time < self.time:  # time went back (a bag played again)
                self._clock_samples.clear()
            self.time = sim_time
            self._clock_samples.append((wall_time, sim_time))
            self._changed()

    def update(self, robot: str, **readings: object) -> None:
        """Set some of a robot's readings (the RobotReadings field names); unknown robots are ignored."""
        with self._lock:
            target = self.robots.get(robot)
            if target is None:
                return
            for name, value in readings.items():
                setattr(target, name, value)
            self._changed()

    def set_ir_raw(self, robot: str, raw: list[float]) -> None:
        distance = ir_sensor.distance_from_raw(np.asarray(raw, dtype=float), self.model.ir_table)
        ranges = np.clip(distance, 0.0, self.model.ir_range)
        self.update(robot, ir_raw=[float(v) for v in raw], ir_range=[round(float(v), 5) for v in ranges])

    def set_swarm(self, step: SwarmArray, wall_time: float) -> None:
        """Every robot's step from one swarm observation (`swarm_messages`): ground truth, odometry, wheel speeds and
        raw IR values of each robot it names, at its stamp, which is also the simulated time shown."""
        columns = {name: step.data[:, index] for name, index in _SWARM_COLUMNS.items()}
        ranges = np.clip(ir_sensor.distance_from_raw(columns['ir_raw'], self.model.ir_table), 0.0, self.model.ir_range)
        values = {name: column.tolist() for name, column in columns.items()}
        values['ir_range'] = np.round(ranges, 5).tolist()
        stamp = step.stamp[0] + step.stamp[1] * 1e-9
        with self._lock:
            for row, name in enumerate(step.robots):
                target = self.robots.get(name)
                if target is not None:
                    target.pose, target.odom = tuple(values['pose'][row]), tuple(values['odom'][row])
                    target.wheel_speeds = tuple(values['wheel_speeds'][row])
                    target.ir_raw, target.ir_range, target.stamp = values['ir_raw'][row], values['ir_range'][row], stamp
        self.set_time(stamp, wall_time)

    def set_detailed(self, robots: frozenset[str]) -> None:
        """The robots pages show in detail now."""
        with self._lock:
            if robots != self.detailed:
                self.detailed = robots
                self._changed()

    def set_ir_range(self, robot: str, sensor: int, distance: float) -> None:
        """One sensor's Range (bags made before `ir_raw` existed): raw value from the table, inf drawn full length."""
        with self._lock:
            target = self.robots.get(robot)
            if target is None:
                return
            sensors = len(self.model.sensor_poses)
            target.ir_raw = target.ir_raw if target.ir_raw is not None else [0.0] * sensors
            target.ir_range = target.ir_range if target.ir_range is not None else [self.model.ir_range] * sensors
            shown = min(distance, self.model.ir_range) if math.isfinite(distance) else self.model.ir_range
            target.ir_raw[sensor] = float(ir_sensor.raw_from_distance(shown, self.model.ir_table))
            target.ir_range[sensor] = round(shown, 5)
            self._changed()

    def set_camera(self, robot: str, png: bytes, stamp: float) -> None:
        """The newest camera image of a robot, as a PNG file, and its simulated time."""
        with self._lock:
            if robot in self.robots:
                self._camera_png[robot] = png
        self.update(robot, camera=stamp)

    def camera_png(self, robot: str) -> bytes | None:
        with self._lock:
            return self._camera_png.get(robot)

    def set_settings(self, **settings: object) -> None:
        with self._lock:
            for name, value in settings.items():
                setattr(self.settings, name, value)
            self._changed()

    def real_time_factor(self, wall_now: float) -> float:
        """Simulated seconds per wall second over the last RTF_WINDOW; 0 when time stands still."""
        with self._lock:
            recent = [(wall, sim) for wall, sim in self._clock_samples if wall >= wall_now - RTF_WINDOW]
        if len(recent) < 2 or recent[-1][0] <= recent[0][0]:
            return 0.0
        return (recent[-1][1] - recent[0][1]) / (wall_now - recent[0][0])

    def wait_for_change(self, version: int, timeout: float) -> int:
        """Block until `version` is outdated (or `timeout`); returns the current version."""
        with self._lock:
            self._lock.wait_for(lambda: self.version != version, timeout)
            return self.version

    def world_json(self) -> str:
        """The world event: arena, obstacles, floor paint, lights, robots' names and starts, and the robot model the
        page draws with."""
        with self._lock:
            world, version = self.world, self.world_version
        model = self.model
        body = {'version': version, 'model': {
            'body_radius': model.body_radius, 'wheel_separation': model.wheel_separation,
            'ir_range': model.ir_range, 'ir_raw_far': float(model.ir_table[-1, 1]),
            'ir_raw_near': float(model.ir_table[0, 1]),
            'sensor_poses': [[float(v) for v in pose] for pose in model.sensor_poses],
            'led_positions': [[float(x), float(y)] for x, y, _ in LED_POSITIONS.tolist()],
            'led_colors': [list(color) for color in LED_COLORS]}}
        if world is not None:
            body.update(_world_body(world))
        return page_json(body)

    def frame_json(self, wall_now: float) -> str:
        """The state event: time, real-time factor reached, settings, every robot's readings (all of them for the
        robots shown in detail); the contacts of all robots, None unless every robot's count is followed; cached per
        version."""
        rtf = round(self.real_time_factor(wall_now), 3)
        with self._lock:
            if self._frame_cache is not None and self._frame_cache[:2] == (self.version, rtf):
                return self._frame_cache[2]
            starts = {r.name: (r.x, r.y, r.yaw) for r in self.world.robots} if self.world is not None else {}
            robots = {name: readings.to_json(starts.get(name, (0.0, 0.0, 0.0))) if name in self.detailed
                      else readings.drawn_json() for name, readings in self.robots.items()}
            counts = [r.collisions for r in self.robots.values()]
            text = page_json({
                'version': self.version, 'world_version': self.world_version, 'time': self.time,
                'rtf': rtf, 'paused': self.settings.paused, 'real_time_factor': self.settings.real_time_factor,
                'collisions': None if None in counts else sum(counts), 'robots': robots})
            self._frame_cache = (self.version, rtf, text)
            return text
