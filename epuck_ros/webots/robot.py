"""`Robot`: Webots' controller API for the e-puck, over the simulator's topics (one per controller process).

Semantics are Webots' (reference manual, `robot.md`): `Robot()` connects to the simulator and returns once it
has the simulator's current step; `step(duration)` hands the motor commands over and returns when `duration`
ms of simulated time have passed, one simulator step per basic time step, with the sensors read at that
instant; it returns -1 once the simulation is ending (Ctrl-C / SIGTERM, or the simulator gone), and, as
Webots does, a controller still running one second after that is stopped. One difference: a controller sees
the simulator from its first step on, so `getTime()` is 0.032 (not 0) before the first `step`.

The runner (`epuck_ros.webots.runner`) calls `configure()` before the script runs; a script run some other
way gets the defaults (the single robot, rclpy's own command line). A headless run (`epuck_ros.webots.headless`)
binds the thread that runs the script to a link of its own (`bind_thread`): the same Robot and devices, stepped
by the pure core in this process instead of by the simulator over ROS. A link has `connect()` (the time step in
seconds), `first_step()` and `answer_and_wait(left, right)` (a `StepData`, None at the end) and `close()`.
"""
from __future__ import annotations

import difflib

import math
import numbers
import signal
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import rclpy
from rclpy.signals import SignalHandlerOptions

from epuck_ros.model import (
    ACCELEROMETER_LOOKUP_TABLE, CAMERA_FOV, CAMERA_NEAR, GROUND_LOOKUP_TABLE,
    GROUND_SENSOR_NAMES, GYRO_LOOKUP_TABLE, LIGHT_LOOKUP_TABLE, LIGHT_SENSOR_NAMES, SENSOR_NAMES, TOF_APERTURE,
    TOF_LOOKUP_TABLE, TOF_NAME, RobotModel)
from epuck_ros.ros.dds_profile import use_package_profile
from epuck_ros.ros.spinning import end_process
from epuck_ros.webots.devices import (
    LED, NANOSECONDS_PER_MS, TURRET_DEVICES, Accelerometer, Camera, Device, DistanceSensor, Gyro, LightSensor, Motor,
    PositionSensor, SampledSensor, TurretSensor, public_methods, report, unsupported)
from epuck_ros.webots.link import TRUTH, LinkError, SimLink, StepData
from epuck_ros.world import TURRET_KINDS

_THREAD = threading.local()
"""A headless run's link (`link`) and its Robot (`robot`), per thread: each robot's script runs in its own."""

MOTOR_NAMES = ('left wheel motor', 'right wheel motor')
ENCODER_NAMES = ('left wheel sensor', 'right wheel sensor')
LED_NAMES = tuple(f'led{i}' for i in range(10))
NOT_SIMULATED = ('speaker', 'emitter', 'receiver')
"""Devices of Webots' e-puck that this simulator does not model."""
SINGLE_ROBOT_NAME = 'epuck'
"""`getName()` of the robot of a one-robot world (its topics carry no name)."""
KILL_DELAY = 1.0
STEP_SILENCE = 5.0
"""Wall seconds without a call to step() after which the script is told (once per stall)."""
STEP_WATCH_PERIOD = 0.5
"""Wall seconds a controller may run on after step() returned -1 (Webots then kills it)."""


@dataclass
class Session:
    """Process-wide state: the runner's choices and the ending of the simulation (signals)."""

    robot: str = ''
    ros_args: list[str] = field(default_factory=list)
    ending: bool = False
    in_step: bool = False

    def start(self) -> None:
        """Start `rclpy` without its own signal handling.

        Ctrl-C inside step() is step's -1, elsewhere KeyboardInterrupt.
        """
        if not rclpy.ok():
            use_package_profile()
            rclpy.init(args=['webots_controller', *self.ros_args], signal_handler_options=SignalHandlerOptions.NO)
        if threading.current_thread() is threading.main_thread():
            for signum in (signal.SIGINT, signal.SIGTERM):
                signal.signal(signum, self._on_signal)

    def _on_signal(self, signum: int, frame: object) -> None:
        """The simulation is ending: step() returns -1 from now on (KeyboardInterrupt outside step()), and, as in
        Webots, the process ends KILL_DELAY later whatever the script does (one caught KeyboardInterrupt and
        went on for ever)."""
        first = not self.ending
        self.ending = True
        if first:
            timer = threading.Timer(KILL_DELAY, end_process, args=(0,))
            timer.daemon = True
            timer.start()
        if not self.in_step:
            raise KeyboardInterrupt


SESSION = Session()


def configure(robot: str, ros_args: list[str]) -> None:
    """The runner's choices, before the script creates its Robot."""
    SESSION.robot = robot
    SESSION.ros_args = list(ros_args)


def bind_thread(link: object, name: str) -> None:
    """The Robot this thread's script creates is robot `name` and talks to `link`, not to the simulator over ROS."""
    _THREAD.link, _THREAD.name, _THREAD.robot = link, name, None


def _first_robot() -> Robot | None:
    return _THREAD.robot if getattr(_THREAD, 'link', None) is not None else Robot.created


class Robot:
    """The e-puck: motors, wheel encoders, ps0..ps7, led0..led9, camera, gs0..gs2, ls0..ls7, accelerometer, gyro,
    the e-puck2's tof, the GPS, Compass and InertialUnit its world puts in its turret slot, simulated time."""

    created: Robot | None = None

    def __init__(self) -> None:
        if _first_robot() is not None:
            report('Error: only one Robot instance can be created per controller process.')
            self.__class__ = _AnotherRobot  # Webots goes on; its API calls act on the one robot there is
            return
        self._ended = False
        """The link said the simulation is over (the simulator gone, or a headless run's end)."""
        self._in_step = False
        self._name, self._link = self._claim_link()
        model = RobotModel()
        time_step = self._link.connect()
        data = self._link.first_step() if time_step is not None else None
        if data is None:
            raise KeyboardInterrupt  # ended (Ctrl-C, or the simulator went away) before the first step
        self._basic_step_ms = time_step * 1000.0
        self._stepping = threading.Lock()
        self._left_step = time.monotonic()
        threading.Thread(target=self._watch_steps, name='step_watch', daemon=True).start()
        self._time_ns = data.time_ns
        self._data = data
        self._build_devices(model)

    def _claim_link(self) -> tuple[str, object]:
        """This robot's name and link: the thread's own (a headless run), else the simulator's over ROS."""
        if getattr(_THREAD, 'link', None) is not None:
            _THREAD.robot = self
            return _THREAD.name, _THREAD.link
        Robot.created = self
        SESSION.start()
        node_name = 'webots_controller' + (f'_{SESSION.robot}' if SESSION.robot else '')
        return SESSION.robot or SINGLE_ROBOT_NAME, SimLink(node_name, SESSION.robot, lambda: SESSION.ending)

    def _build_devices(self, model: RobotModel) -> None:
        """The e-puck's devices, wired to note what the next step must ask for or send."""
        now = lambda: self._time_ns  # noqa: E731 - the devices' view of simulated time
        self._encoders = [PositionSensor(name, now) for name in ENCODER_NAMES]
        self._motors = [Motor(name, model.max_wheel_speed, encoder)
                        for name, encoder in zip(MOTOR_NAMES, self._encoders)]
        self._distance_sensors = [DistanceSensor(name, now, model.ir_table, model.ir_aperture)
                                  for name in SENSOR_NAMES]
        self._leds = [LED(name) for name in LED_NAMES]
        self._camera = Camera('camera', now, *self._link.camera_size, CAMERA_FOV, CAMERA_NEAR)   # the sim's size
        self._ground_sensors = [DistanceSensor(name, now, GROUND_LOOKUP_TABLE, 0.0) for name in GROUND_SENSOR_NAMES]
        self._light_sensors = [LightSensor(name, now, LIGHT_LOOKUP_TABLE) for name in LIGHT_SENSOR_NAMES]
        self._accelerometer = Accelerometer('accelerometer', now, ACCELEROMETER_LOOKUP_TABLE)
        self._gyro = Gyro('gyro', now, GYRO_LOOKUP_TABLE)
        self._tof = DistanceSensor(TOF_NAME, now, TOF_LOOKUP_TABLE, TOF_APERTURE)
        self._turret: list[TurretSensor] = [TURRET_DEVICES[device.kind](device.name, now)
                                            for device in self._link.turret]
        self._senses: dict[str, list[SampledSensor]] = {
            'camera': [self._camera], 'ground': self._ground_sensors, 'light': self._light_sensors,
            'imu': [self._accelerometer, self._gyro], 'tof': [self._tof], TRUTH: list(self._turret)}
        """The devices of each sense the simulator computes on demand: enabling one asks for the sense."""
        self._to_ask = self._to_send = False
        """A device was enabled, an LED changed, since the last step: the next one asks for senses, sends LEDs."""
        for device in (device for devices in self._senses.values() for device in devices):
            device.on_enable = self._note_enabled
        for led in self._leds:
            led.on_change = self._note_led
        self._devices: dict[str, Device] = {
            device.getName(): device
            for device in (*self._motors, *self._encoders, *self._distance_sensors, *self._ground_sensors,
                           *self._light_sensors, self._camera, self._accelerometer, self._gyro, self._tof,
                           *self._leds)}
        for device in self._turret:
            if device.getName() in self._devices:
                raise LinkError(f'the world gives robot "{self._name}" a turret device named "{device.getName()}", the '
                                f'name of one of the e-puck\'s own devices: give it another name in the world file')
            self._devices[device.getName()] = device

    # --- time ---------------------------------------------------------------------------------------------------

    def getBasicTimeStep(self) -> float:
        """The simulator's step in ms (its `time_step` parameter): 32.0 by default."""
        return self._basic_step_ms

    def getTime(self) -> float:
        return self._time_ns * 1e-9

    def step(self, duration: int | None = None) -> int:
        """Advance `duration` ms (default: one basic step; 0: none) in whole simulator steps; -1 once the
        simulation is ending, else 0. Without lockstep a slow controller may find more time has passed."""
        if duration is None:
            duration = int(self._basic_step_ms)
        if SESSION.ending or self._ended:
            return -1
        if not isinstance(duration, numbers.Real) or not math.isfinite(duration):
            report(f'Error: wb_robot_step() called with an invalid duration ({duration!r}): it takes a whole number '
                   f'of milliseconds.')
            return 0
        if duration < 0:
            report('Error: wb_robot_step() called with a negative duration.')
            return 0
        with self._stepping:   # a script stepping from several threads: one step at a time, as Webots serialises
            return self._step(duration)

    def _watch_steps(self) -> None:
        """Say once per stall when the script has not called step() for `STEP_SILENCE` wall seconds: the simulation
        waits for it (lockstep) or drives on without it, and an endless loop otherwise shows nothing at all."""
        said_for = None
        while not (SESSION.ending or self._ended):
            time.sleep(STEP_WATCH_PERIOD)
            left = self._left_step
            if not self._in_step and time.monotonic() - left >= STEP_SILENCE and said_for != left:
                said_for = left
                report(f'{Path(sys.argv[0]).name} has not called robot.step() for {STEP_SILENCE:g} s (at simulated '
                       f't={self.getTime():.3f} s): the simulator waits for its answer; an endless loop without '
                       f'step() never lets time go on.')

    def _step(self, duration: float) -> int:
        # Whole simulator steps, rounded up: step(16) or step(40) with a 32 ms basic step take one and two steps.
        steps = math.ceil(duration / self._basic_step_ms - 1e-9)
        target_ns = self._time_ns + round((steps - 0.5) * self._basic_step_ms * NANOSECONDS_PER_MS)
        SESSION.in_step = self._in_step = True
        try:
            if self._to_ask or self._to_send:
                self._ask_for_senses()
            left_motor, right_motor = self._motors
            while self._time_ns < target_ns:
                left_angle, right_angle = self._data.wheel_angles
                data = self._link.answer_and_wait(left_motor.command(left_angle), right_motor.command(right_angle))
                if data is None:
                    self._ended = True
                    return -1
                self._read(data)
        finally:
            SESSION.in_step = self._in_step = False
            self._left_step = time.monotonic()
        return -1 if SESSION.ending else 0

    def _note_enabled(self) -> None:
        self._to_ask = True

    def _note_led(self) -> None:
        self._to_send = True

    def _ask_for_senses(self) -> None:
        """The senses of enabled devices are gathered from now on; the LEDs set since the last step are sent."""
        self._to_ask = self._to_send = False   # first: a device enabled meanwhile (another thread) is asked next step
        for kind, devices in self._senses.items():
            if any(device.enabled for device in devices):
                self._link.want(kind)
        if any(led.changed for led in self._leds):
            self._link.publish_leds([led.get() for led in self._leds])
            for led in self._leds:
                led.changed = False

    def _read(self, data: StepData) -> None:
        self._data = data
        self._time_ns = data.time_ns
        for encoder, angle, speed in zip(self._encoders, data.wheel_angles, data.wheel_speeds):
            encoder.sample_with_speed(data.time_ns, angle, speed)
        for sensor, value in zip(self._distance_sensors, data.ir_raw):
            sensor.sample(data.time_ns, value)
        senses = data.senses
        if senses:
            time_ns = data.time_ns
            if 'camera' in senses:
                self._camera.sample(time_ns, senses['camera'])
            for sensor, value in zip(self._ground_sensors, senses.get('ground', ())):
                sensor.sample(time_ns, value)
            for sensor, value in zip(self._light_sensors, senses.get('light', ())):
                sensor.sample(time_ns, value)
            if 'imu' in senses:
                self._accelerometer.sample(time_ns, senses['imu'][0])
                self._gyro.sample(time_ns, senses['imu'][1])
            if 'tof' in senses:
                self._tof.sample(time_ns, senses['tof'])
            if TRUTH in senses:
                for device in self._turret:
                    device.sample(time_ns, senses[TRUTH])

    # --- devices ------------------------------------------------------------------------------------------------

    def getName(self) -> str:
        return self._name

    def getDevice(self, name: str) -> Device | None:
        device = self._devices.get(name)
        if device is None:
            kind = next((kind for kind, default in TURRET_KINDS.items() if default == name), None)
            if kind is not None:
                self._refuse_missing(kind, name)
            if name in NOT_SIMULATED:
                report(f'Device "{name}" exists on Webots\' e-puck but is not simulated by epuck_ros '
                       f'(devices: {", ".join(self._devices)})')
            else:
                close = difflib.get_close_matches(str(name), list(self._devices), n=1)
                hint = f' (did you mean "{close[0]}"?)' if close else ''
                report(f'Device "{name}" was not found on robot "{self._name}"{hint}')
        return device

    def _refuse_missing(self, kind: str, name: str) -> None:
        """A turret device the world does not give: the script ends with one line that says how to add it (Webots
        would return None, and the script fail later on a NoneType)."""
        example = kind if name == TURRET_KINDS[kind] else f'{{type: {kind}, name: {name}}}'
        raise LinkError(f'robot "{self._name}" has no {kind} named "{name}": its world gives it none. Add one to the '
                        f'robot\'s turret slot in the world file, e.g. robot: {{start: [0, 0, 0], turret: '
                        f'[{example}]}} (or turret: [{example}] in its entry of robots:)')

    def _typed(self, getter: str, kind: str, name: str) -> Device | None:
        """getGPS, getCompass, getInertialUnit: deprecated forwarders to getDevice that know the type they want."""
        report(f'DEPRECATION: Robot.{getter} is deprecated, please use Robot.getDevice instead.')
        device = self._devices.get(name)
        if not isinstance(device, TURRET_DEVICES[kind]):
            self._refuse_missing(kind, name)
        return device

    def getGPS(self, name: str) -> Device | None:
        return self._typed('getGPS', 'GPS', name)

    def getCompass(self, name: str) -> Device | None:
        return self._typed('getCompass', 'Compass', name)

    def getInertialUnit(self, name: str) -> Device | None:
        return self._typed('getInertialUnit', 'InertialUnit', name)

    def getNumberOfDevices(self) -> int:
        return len(self._devices)

    def getDeviceByIndex(self, index: int) -> Device:
        return list(self._devices.values())[index]

    def _deprecated(self, getter: str, name: str) -> Device | None:
        report(f'DEPRECATION: Robot.{getter} is deprecated, please use Robot.getDevice instead.')
        return self.getDevice(name)

    def getMotor(self, name: str) -> Device | None:
        return self._deprecated('getMotor', name)

    def getDistanceSensor(self, name: str) -> Device | None:
        return self._deprecated('getDistanceSensor', name)

    def getPositionSensor(self, name: str) -> Device | None:
        return self._deprecated('getPositionSensor', name)

    def getCamera(self, name: str) -> Device | None:
        return self._deprecated('getCamera', name)

    def getLightSensor(self, name: str) -> Device | None:
        return self._deprecated('getLightSensor', name)

    def getAccelerometer(self, name: str) -> Device | None:
        return self._deprecated('getAccelerometer', name)

    def getGyro(self, name: str) -> Device | None:
        return self._deprecated('getGyro', name)

    def getLED(self, name: str) -> Device | None:
        return self._deprecated('getLed', name)  # sic: Webots' message says getLed

    def __getattr__(self, name: str) -> object:  # only called for names the class does not define
        if name.startswith('_'):
            raise AttributeError(name)
        raise unsupported('Robot', name, public_methods(Robot))


class _AnotherRobot(Robot):
    """A second Robot(): Webots prints an error and goes on; here its calls act on the first Robot."""

    def __getattribute__(self, name: str) -> object:
        if name in ('__class__', '__dict__'):
            return object.__getattribute__(self, name)
        return getattr(_first_robot(), name)


def close() -> None:
    """The runner's end: the Robot's node goes (the simulator's cmd_timeout then stops the wheels)."""
    link = getattr(Robot.created, '_link', None)  # None: no Robot, or it failed before connecting
    if link is not None:
        link.close()
