"""The e-puck's Webots devices as plain objects, with the semantics of Webots' reference manual; no ROS here.

What each call does, and every message text, follows the Webots controller library (`src/controller/c/motor.c`,
`distance_sensor.c`, `position_sensor.c`, `gps.c`, `compass.c`, `inertial_unit.c`) and the reference pages `motor.md`,
`distancesensor.md`, `positionsensor.md`, `led.md`, `camera.md`, `lightsensor.md`, `accelerometer.md`, `gyro.md`,
`gps.md`, `compass.md`, `inertialunit.md` (cyberbotics/webots).
Nothing here knows where the readings come from (the simulator over ROS, or the core in this process).
The robot (`epuck_ros.webots.robot`) hands each sensor the
readings of every simulator step (`sample`) and asks each motor for the wheel speed of the next step (`command`).

A name a script uses that Webots has but this shim does not is refused with `UnsupportedError`, which says so
and lists what is supported, instead of Python's bare AttributeError.
"""
from __future__ import annotations

import math
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

from epuck_ros.sensors import turret
from epuck_ros.sensors.png import png_bytes

NANOSECONDS_PER_MS = 1_000_000
MOTOR_CONTROL_P = 10.0
"""Webots' default controlPID P gain: the motor's position controller (I and D are 0 by default)."""


def report(message: str) -> None:
    """Webots prints its controller-library errors and warnings on stderr; so do we."""
    print(message, file=sys.stderr, flush=True)


class UnsupportedError(AttributeError):
    """A Webots API name this shim does not provide (an AttributeError, so `hasattr` still works)."""


def unsupported(owner: str, name: str, supported: list[str]) -> UnsupportedError:
    return UnsupportedError(
        f'{owner}.{name} is part of the Webots API but not supported by epuck_ros\'s Webots shim; '
        f'{owner} supports: {", ".join(supported)}')


def _nothing() -> None:
    """A device's listener until the robot sets its own."""


def public_methods(cls: type) -> list[str]:
    return sorted(name for name in dir(cls) if not name.startswith('_') and callable(getattr(cls, name)))


class Device:
    """What every Webots device has: a name; unknown Webots calls are named in a clear error."""

    def __init__(self, name: str) -> None:
        self._name = name

    def getName(self) -> str:
        return self._name

    def __getattr__(self, name: str) -> object:  # only called for names the class does not define
        if name.startswith('_'):
            raise AttributeError(name)
        raise unsupported(type(self).__name__, name, public_methods(type(self)))

    def __repr__(self) -> str:
        return f'<{type(self).__name__} {self._name!r}>'


POSITION_MODE_HINT_STEPS = 94
"""Steps (3 s of 32 ms) of velocity commands on a motor left in position control before the hint: the wheel stays
still, silently, in Webots as here, and students lose their first hour to it."""


class Motor(Device):
    """A wheel's RotationalMotor: position control by default, velocity control after `setPosition(inf)`.

    Position control is Webots' own: each step the motor runs at P x (target - angle), at most at the set
    velocity, on the wheel's encoder angle (Webots uses the exact joint angle; the encoder is within 2π/1000 rad).
    """

    def __init__(self, name: str, max_velocity: float, encoder: PositionSensor) -> None:
        super().__init__(name)
        self._encoder = encoder
        encoder.motor = self
        self._max_velocity = max_velocity
        self._velocity = max_velocity  # Webots starts a motor's velocity at its maxVelocity
        self._target: float | None = None  # None: hold the angle of the first reading (the joint's start)
        self._position_never_set = True
        self._velocity_requested = False
        self._held_steps = 0

    def setPosition(self, position: float) -> None:
        position = float(position)
        if math.isnan(position):
            report("Error: wb_motor_set_position() called with an invalid 'position' argument (NaN).")
            return
        self._target = position
        self._position_never_set = False

    def getTargetPosition(self) -> float:
        return 0.0 if self._target is None else self._target

    def setVelocity(self, velocity: float) -> None:
        velocity = float(velocity)
        if math.isnan(velocity):
            report("Error: wb_motor_set_velocity() called with an invalid 'velocity' argument.(NaN)")
            return
        if velocity < 0.0 and not self.in_velocity_mode:
            report(f"Error: wb_motor_set_velocity() called with negative 'velocity' argument in position control "
                   f"mode ({self.getTargetPosition():g}).")
            return
        if abs(velocity) > self._max_velocity:
            report(f'WARNING: RotationalMotor "{self._name}": The requested velocity {velocity:g} exceeds '
                   f"'maxVelocity' = {self._max_velocity:g}.")
        self._velocity = velocity
        self._velocity_requested = self._velocity_requested or velocity != 0.0

    def getVelocity(self) -> float:
        """The velocity as set (Webots' library returns the request; the simulator applies it clamped)."""
        return self._velocity

    def getMaxVelocity(self) -> float:
        return self._max_velocity

    def getPositionSensor(self) -> PositionSensor:
        """The encoder on the same wheel joint."""
        return self._encoder

    def getMinPosition(self) -> float:
        return 0.0  # Webots: minPosition = maxPosition = 0 means no limit, as on the e-puck's wheels

    def getMaxPosition(self) -> float:
        return 0.0

    @property
    def in_velocity_mode(self) -> bool:
        return self._target is not None and math.isinf(self._target)

    def command(self, angle: float) -> float:
        """The wheel speed (rad/s) for the next step, given the wheel's encoder angle now."""
        limit = min(abs(self._velocity), self._max_velocity)
        if self.in_velocity_mode:
            return math.copysign(limit, self._velocity)
        if self._target is None:
            self._target = angle
        if self._position_never_set and self._velocity_requested:
            self._held_steps += 1
            if self._held_steps == POSITION_MODE_HINT_STEPS:
                report(f'Hint (not from Webots): motor "{self._name}" has had velocities set for '
                       f'{POSITION_MODE_HINT_STEPS} steps but is in position control (setPosition was never '
                       f'called), so it holds its angle and the wheel stays still: call '
                       f'setPosition(float(\'inf\')) once for velocity control, as the course\'s controllers do.')
        return max(-limit, min(limit, MOTOR_CONTROL_P * (self._target - angle)))


class SampledSensor(Device):
    """A sensor read every sampling period: NaN until the first period has elapsed after `enable`."""

    API_PREFIX = ''
    """The C function prefix Webots' messages name, e.g. `wb_distance_sensor`."""

    def __init__(self, name: str, now_ns: Callable[[], int]) -> None:
        super().__init__(name)
        self._now_ns = now_ns
        self._period_ms = 0
        self._due_ns = 0
        self._value = math.nan
        self.on_enable: Callable[[], None] = _nothing
        """Called by `enable`: the robot then asks for the sense, not each step whether it is wanted."""

    def enable(self, samplingPeriod: int) -> None:
        period = int(samplingPeriod)
        if period < 0:
            report(f'Error: {self.API_PREFIX}_enable() called with negative sampling period.')
            return
        self._period_ms = period
        self._due_ns = self._now_ns() + period * NANOSECONDS_PER_MS
        self.on_enable()

    def disable(self) -> None:
        self.enable(0)

    def getSamplingPeriod(self) -> int:
        return self._period_ms

    def getValue(self) -> float:
        if self._period_ms <= 0:
            report(f'Error: {self.API_PREFIX}_get_value() called for a disabled device! Please use: '
                   f'{self.API_PREFIX}_enable().')
        return self._value

    @property
    def enabled(self) -> bool:
        """Whether the script has enabled the sensor: the simulator computes a sense only while one is."""
        return self._period_ms > 0

    def sample(self, time_ns: int, value: object) -> None:
        """The simulator's reading at `time_ns`: kept if a sampling period has elapsed since the last one."""
        due_ns = self._due_ns
        if self._period_ms <= 0 or time_ns < due_ns:
            return
        self._value = self._keep(value)
        period_ns = self._period_ms * NANOSECONDS_PER_MS
        self._due_ns = due_ns + ((time_ns - due_ns) // period_ns + 1) * period_ns   # the first period's end after it

    _keep: Callable[[object], object] = staticmethod(float)
    """The value as getValue() gives it (a plain function: it is called for every sensor each step)."""


class DistanceSensor(SampledSensor):
    """A DistanceSensor: psN (the ring) or gsN (the ground sensors), infra-red, or the e-puck2's tof, generic;
    getValue() is the raw lookup-table value, with the simulator's noise."""

    API_PREFIX = 'wb_distance_sensor'

    def __init__(self, name: str, now_ns: Callable[[], int], lookup_table: np.ndarray, aperture: float) -> None:
        super().__init__(name, now_ns)
        self._table = lookup_table
        self._aperture = aperture

    def getMinValue(self) -> float:
        return float(self._table[:, 1].min())

    def getMaxValue(self) -> float:
        return float(self._table[:, 1].max())

    def getAperture(self) -> float:
        return self._aperture

    def getLookupTable(self) -> list[float]:
        """The table as Webots gives it: distance, value, noise of each row, flattened."""
        return [float(x) for x in self._table.ravel()]


class PositionSensor(SampledSensor):
    """A wheel encoder: radians, from the simulator's quantised wheel angle."""

    API_PREFIX = 'wb_position_sensor'

    def __init__(self, name: str, now_ns: Callable[[], int]) -> None:
        super().__init__(name, now_ns)
        self._speed = math.nan
        self.motor: Motor | None = None
        """The motor on the same wheel joint (set by the Motor)."""

    def sample_with_speed(self, time_ns: int, angle: float, speed: float) -> None:
        if self._period_ms > 0 and time_ns >= self._due_ns:
            self._speed = float(speed)
        self.sample(time_ns, angle)

    def getVelocity(self) -> float:
        return self._speed

    def getMotor(self) -> Motor | None:
        return self.motor


class LED(Device):
    """An e-puck LED: 0 off, 1 on (its one colour); the state lives in the controller, the simulator is told of
    changes (`changed`) so the view can draw them."""

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self._value = 0
        self.changed = False
        """Set since the robot last sent the LEDs to the simulator (the robot clears it)."""
        self.on_change: Callable[[], None] = _nothing
        """Called when `changed` is set: the robot then sends the LEDs, not each step whether one changed."""

    def set(self, value: int) -> None:
        value = int(value)
        if value != self._value:
            self.changed = True
            self.on_change()
        self._value = value

    def get(self) -> int:
        return self._value


class LightSensor(SampledSensor):
    """A light sensor lsN: getValue() is the proto's lookup table of the irradiance (4095 in the dark, 0 in bright
    light)."""

    API_PREFIX = 'wb_light_sensor'

    def __init__(self, name: str, now_ns: Callable[[], int], lookup_table: np.ndarray) -> None:
        super().__init__(name, now_ns)
        self._table = lookup_table

    def getLookupTable(self) -> list[float]:
        return [float(x) for x in self._table.ravel()]


class VectorSensor(SampledSensor):
    """A three-axis sensor: getValues() is [x, y, z] in the robot's frame (x forward, y left, z up), NaN until the
    first sampling period has elapsed."""

    def __init__(self, name: str, now_ns: Callable[[], int], lookup_table: np.ndarray) -> None:
        super().__init__(name, now_ns)
        self._table = lookup_table
        self._value = [math.nan] * 3

    def _keep(self, value: object) -> list[float]:
        return [float(v) for v in value]   # type: ignore[attr-defined]

    def getValues(self) -> list[float]:
        if self._period_ms <= 0:
            report(f'Error: {self.API_PREFIX}_get_values() called for a disabled device! Please use: '
                   f'{self.API_PREFIX}_enable().')
        return list(self._value)

    def getValue(self) -> float:
        raise unsupported(type(self).__name__, 'getValue', public_methods(type(self)))

    def getLookupTable(self) -> list[float]:
        return [float(x) for x in self._table.ravel()]


class Accelerometer(VectorSensor):
    """m/s^2 through the proto's table (the identity within +-100): [0, 0, 9.81] at rest."""

    API_PREFIX = 'wb_accelerometer'


class Gyro(VectorSensor):
    """The proto's table turns rad/s into its units: 100,000 / 13.315805 per rad/s."""

    API_PREFIX = 'wb_gyro'


class Camera(SampledSensor):
    """The e-puck's camera: an RGB image each sampling period, handed out as Webots does.

    `getImage()` is Webots' buffer: BGRA bytes, 4 per pixel, row by row from the top left; `getImageArray()` is
    image[x][y] = [r, g, b] (x the column); `imageGetRed/Green/Blue/Gray(image, width, x, y)` read one pixel of the
    buffer (gray the integer mean of the three). Before the first period has elapsed there is no image (None).
    """

    API_PREFIX = 'wb_camera'

    def __init__(self, name: str, now_ns: Callable[[], int], width: int, height: int, fov: float,
                 near: float) -> None:
        super().__init__(name, now_ns)
        self._width, self._height, self._fov, self._near = width, height, fov, near
        self._value = None
        self._bgra: bytes | None = None

    def _keep(self, value: object) -> np.ndarray:
        """The image as the simulator made it, (height, width, 3): its size is the camera's from then on (the sim's
        camera_width and camera_height may differ from the size the robot was built with)."""
        rgb = np.asarray(value, dtype=np.uint8)
        if rgb.ndim != 3:
            rgb = rgb.reshape(self._height, self._width, 3)
        self._height, self._width = rgb.shape[:2]
        self._bgra = None   # made on demand: a script may only read getImageArray
        return rgb

    def getImage(self) -> bytes | None:
        if self._period_ms <= 0:
            report('Error: wb_camera_get_image() called for a disabled device! Please use: wb_camera_enable().')
        rgb = self._value
        if rgb is None:
            return None
        if self._bgra is None:
            bgra = np.empty((self._height, self._width, 4), dtype=np.uint8)
            bgra[..., 0], bgra[..., 1], bgra[..., 2], bgra[..., 3] = rgb[..., 2], rgb[..., 1], rgb[..., 0], 255
            self._bgra = bgra.tobytes()
        return self._bgra

    def getImageArray(self) -> list[list[list[int]]] | None:
        image = self.getImage()
        if image is None:
            return None
        return self._value.transpose(1, 0, 2).tolist()   # type: ignore[union-attr]

    @staticmethod
    def imageGetRed(image: bytes, width: int, x: int, y: int) -> int:
        return image[4 * (y * width + x) + 2]

    @staticmethod
    def imageGetGreen(image: bytes, width: int, x: int, y: int) -> int:
        return image[4 * (y * width + x) + 1]

    @staticmethod
    def imageGetBlue(image: bytes, width: int, x: int, y: int) -> int:
        return image[4 * (y * width + x)]

    @staticmethod
    def imageGetGray(image: bytes, width: int, x: int, y: int) -> int:
        offset = 4 * (y * width + x)
        return (image[offset] + image[offset + 1] + image[offset + 2]) // 3

    imageGetGrey = imageGetGray

    def getWidth(self) -> int:
        return self._width

    def getHeight(self) -> int:
        return self._height

    def getFov(self) -> float:
        return self._fov

    def getNear(self) -> float:
        return self._near

    def saveImage(self, filename: str, quality: int) -> int:
        """0 on success, -1 on failure (no image yet, a file that cannot be written, an extension other than .png;
        Webots also writes .jpg, which this shim cannot: it says so)."""
        if self._value is None:
            return -1
        suffix = Path(str(filename)).suffix.lower()
        if suffix in ('.jpg', '.jpeg'):
            report(f'Error: wb_camera_save_image(): JPEG is not supported by epuck_ros\'s Webots shim, save '
                   f'"{Path(str(filename)).with_suffix(".png").name}" instead.')
            return -1
        if suffix != '.png':
            return -1
        try:
            Path(str(filename)).write_bytes(png_bytes(self._value))
        except OSError:
            return -1
        return 0


class TurretSensor(SampledSensor):
    """A device of the turret slot (a world gives it: `turret` in the world file), read from the robot's true state
    (`sensors.turret.Truth`); its values are NaN until the first sampling period has elapsed."""

    def __init__(self, name: str, now_ns: Callable[[], int]) -> None:
        super().__init__(name, now_ns)
        self._value = None

    def _keep(self, value: object) -> turret.Truth:
        return turret.Truth(*value)   # type: ignore[misc]

    def _read(self, function: Callable[[turret.Truth], list[float]], api: str, count: int = 3) -> list[float]:
        if self._period_ms <= 0:
            report(f'Error: {self.API_PREFIX}_{api}() called for a disabled device! Please use: '
                   f'{self.API_PREFIX}_enable().')
        return [math.nan] * count if self._value is None else function(self._value)

    def getValue(self) -> float:
        raise unsupported(type(self).__name__, 'getValue', public_methods(type(self)))


class GPS(TurretSensor):
    """Webots' GPS with WorldInfo's defaults (local coordinates, reference 0 0 0, no noise): its position in the world
    (x, y as the world file's, z 0.0486 above the floor), its velocity and speed."""

    API_PREFIX = 'wb_gps'
    LOCAL, WGS84 = 0, 1

    def getValues(self) -> list[float]:
        return self._read(turret.gps_values, 'get_values')

    def getSpeedVector(self) -> list[float]:
        return self._read(turret.gps_speed_vector, 'get_speed_vector')

    def getSpeed(self) -> float:
        return math.hypot(*self.getSpeedVector())

    def getCoordinateSystem(self) -> int:
        return self.LOCAL


class Compass(TurretSensor):
    """Webots' Compass in an ENU world: the north, +y, in the robot's frame (1, 0, 0 when facing +y)."""

    API_PREFIX = 'wb_compass'

    def getValues(self) -> list[float]:
        return self._read(turret.compass_values, 'get_values')

    def getLookupTable(self) -> list[float]:
        return []


class InertialUnit(TurretSensor):
    """Webots' InertialUnit in an ENU world: roll, pitch, yaw (yaw 0 facing +x, counter-clockwise positive) and the
    quaternion [x, y, z, w] of the robot's rotation."""

    API_PREFIX = 'wb_inertial_unit'

    def getRollPitchYaw(self) -> list[float]:
        return self._read(turret.roll_pitch_yaw, 'get_roll_pitch_yaw')

    def getQuaternion(self) -> list[float]:
        return self._read(turret.quaternion, 'get_quaternion', 4)

    def getNoise(self) -> float:
        return 0.0


TURRET_DEVICES: dict[str, type[TurretSensor]] = {'GPS': GPS, 'Compass': Compass, 'InertialUnit': InertialUnit}
"""The device class of each turret type a world can give (`world.TURRET_KINDS`)."""
