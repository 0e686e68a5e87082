"""N independent Avoid worlds stepped together on the pure core: one e-puck each, one random generator each.

All worlds live in one `Simulation(isolated=True)`: its robots neither touch nor see each other, and its one-robot
and many-robot paths give the same bits, so world i of N is exactly a lone world with the same generator. The
simulator runs without noise and the IR noise is drawn here, per world, with Webots' formula (value times 1 +
sigma N(0, 1), sigma from the lookup table's third column): then a world's noise does not depend on how many
worlds share the simulator. Each generator draws, in order: the start pose at reset (again until the body is clear
of everything), eight normals for the readings at reset, eight more at each step.

Observation (float32, 10 values): the eight IR activations, each 1 - d / 0.0673 for the distance d (m) the raw value
stands for on the lookup table (`activations`: 0 with nothing seen, 0.70 at 2 cm), then the two wheel
speeds applied in the last step as fractions of the maximum, in [-1, 1] (the speeds commanded: a blocked robot's
wheels turn on). Action: the two wheel speeds (left, right) as fractions of the maximum (6.28 rad/s), in [-1, 1]; a
finite value beyond is clipped to it (as the wheels clamp a speed beyond their maximum), NaN and infinities are
refused (`check_actions`). Reward: Floreano and Mondada's fitness of the step, V (1 - sqrt(dv)) (1 - i) in [-1, 1]
(see `fitness`).
"""
from __future__ import annotations

import math

import numpy as np

from epuck_ros.behaviours.base import FREE_READING_SIGMAS
from epuck_ros.ir_sensor import LookupTable, distance_from_raw
from epuck_ros.kinematics import wheels_from_twist
from epuck_ros.model import TIME_STEP, RobotModel
from epuck_ros.simulation import CommandError, Simulation
from epuck_ros.world import CONTACT_TOLERANCE, ROBOT_GAP, RobotStart, World

OBSERVATION_SIZE = 10
"""Eight IR activations and two wheel speeds."""
MAX_WORLDS = 65536
"""Most worlds one vector environment steps together: a bound on what a typo in `num_envs` can allocate."""


def fitness(wheels: np.ndarray, activation: np.ndarray) -> np.ndarray:
    """Floreano and Mondada's Phi = V (1 - sqrt(dv)) (1 - i) per world, in [-1, 1]: V the mean of the two wheel
    speeds, signed (backward motion counts against), dv the absolute difference of the wheel speeds over 2, i the
    highest IR activation, each of the last two in [0, 1]. wheels (N, 2): the wheel speeds of the body's true motion
    as fractions of the maximum; activation (N, 8) -> (N,).

    Two departures, both loopholes that evolution found here and the paper's robot did not offer (its motors could
    not reverse from one step to the next): the wheels are those of the body's true motion (a blocked robot's
    wheels count as still, as a real robot's stall or slip; the simulator's own wheels turn on, and evolution
    parked robots in a corner with the motors at full speed), and V is signed. Our motors change speed at once:
    with V the mean absolute speed evolution found full reverse and full forward on alternate steps (V = 1, dv = 0,
    no obstacle ever near), and with V forward only (reversing 0) the same alternation in place earned 0.5 a step
    with no risk, more than driving the corridor world; signed, going back and forth earns nothing, as it gets
    nowhere.
    """
    left, right = wheels[:, 0], wheels[:, 1]
    speed = 0.5 * (left + right)
    turning = 0.5 * np.abs(left - right)
    return speed * (1.0 - np.sqrt(turning)) * (1.0 - activation.max(axis=1))


def step_rewards(sim: Simulation, activation: np.ndarray, model: RobotModel) -> np.ndarray:
    """Each robot's `fitness` of the step `sim` just took, from its body's true motion: the one reward of Avoid-v0
    and swarm_avoid_v0 (a robot pushing into a wall earns nothing, whatever its motors do). activation (N, 8)."""
    twist = sim.true_twist
    left, right = wheels_from_twist(twist[:, 0], twist[:, 1], model)
    return fitness(np.column_stack([left, right]) / model.max_wheel_speed, activation)


def episode_steps(duration: object, noise: object, time_step: float = TIME_STEP) -> int:
    """The steps of an episode of `duration` simulated seconds; ValueError naming the argument for a bad duration
    or a `noise` that is not a bool (the checks every environment's constructor shares)."""
    if not (isinstance(duration, (int, float)) and math.isfinite(duration) and 0.0 < duration <= 1e6):
        raise ValueError(f'duration must be a number of simulated seconds in (0, 1e6], got {duration!r}')
    if not isinstance(noise, bool):
        raise ValueError(f'noise must be True or False, got {noise!r}')
    return max(1, math.ceil(duration / time_step - 1e-9))


class Worlds:
    """`count` Avoid worlds in `world` (its robots ignored), `duration` simulated seconds per episode."""

    def __init__(self, count: int, world: World, duration: float, noise: bool = True,
                 model: RobotModel = RobotModel(), time_step: float = TIME_STEP) -> None:
        if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or not 1 <= count <= MAX_WORLDS:
            raise ValueError(f'num_envs must be an integer from 1 to {MAX_WORLDS}, got {count!r}')
        self.count, self.world, self.model, self.time_step = int(count), world, model, time_step
        self.noise = noise
        self.episode_steps = episode_steps(duration, noise, time_step)
        table = model.ir_table
        self._table, self._reach = LookupTable(table), reach(model)
        self._noise_raws, self._noise_sigmas = table[::-1, 1].copy(), table[::-1, 2].copy()
        self.sim: Simulation | None = None
        self.rngs: list[np.random.Generator] = []
        self.steps = 0
        self._activation: np.ndarray | list[float] = np.zeros((count, 8))
        self._normals = np.empty((count, 8))

    # --- episodes -----------------------------------------------------------------------------------------

    def reset(self, rngs: list[np.random.Generator]) -> np.ndarray:
        """A new episode in every world, drawn from its generator; the observations (count, 10)."""
        self.rngs = rngs
        starts = self._start_poses()
        robots = [RobotStart(f'w{i}', x, y, yaw) for i, (x, y, yaw) in enumerate(starts.tolist())]
        self.sim = Simulation(self.world.with_robots(robots), model=self.model, time_step=self.time_step,
                              noise=False, cmd_timeout=0.0, isolated=True)
        self.steps = 0
        return self._observe()

    def _start_poses(self) -> np.ndarray:
        """(count, 3) start poses, uniform over the arena and headings, redrawn until clear of every obstacle."""
        radius = self.model.body_radius + ROBOT_GAP + CONTACT_TOLERANCE
        half_x, half_y = (size / 2.0 - radius for size in self.world.arena_size)
        low, high = np.array([-half_x, -half_y, -math.pi]), np.array([half_x, half_y, math.pi])
        poses = np.empty((self.count, 3))
        todo = np.arange(self.count)
        for _ in range(10000):
            for i in todo.tolist():
                poses[i] = self.rngs[i].uniform(low, high)
            clear = self.world.discs_clear(poses[todo, :2], radius)
            todo = todo[~clear]
            if not len(todo):
                return poses
        raise ValueError('the world has no room for an e-puck clear of its walls and obstacles')

    # --- steps --------------------------------------------------------------------------------------------

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:
        """Drive every world one step with `actions` (count, 2), checked by `check_actions`; (observations, rewards,
        truncated: the same for every world, whose episodes all last `episode_steps`)."""
        sim = self.sim
        top = self.model.max_wheel_speed
        sim.command_all_wheels(actions * top)
        sim.step()
        self.steps += 1
        observation = self._observe()
        return observation, step_rewards(sim, self.last_activation, self.model), self.steps >= self.episode_steps

    def step_one(self, left: float, right: float) -> tuple[np.ndarray, float, bool]:
        """`step` of the one world (count 1) on Python floats: `step`'s arithmetic operation for operation (the same
        bits: test_envs checks), without NumPy's per-call cost on eight values; (observation (10,), reward,
        truncated)."""
        sim, top = self.sim, self.model.max_wheel_speed
        sim.command_wheels(0, left * top, right * top)
        sim.step()
        self.steps += 1
        raw = sim.ir_raw[0]
        if self.noise:
            sigmas = np.interp(raw, self._noise_raws, self._noise_sigmas).tolist()
            raw = [value * (1.0 + sigma * normal)
                   for value, sigma, normal in zip(raw.tolist(), sigmas, self.rngs[0].standard_normal(8).tolist())]
        else:
            raw = raw.tolist()
        table, farthest = self._table, self._reach
        activation = [1.0 - min(table.range_of(value), farthest) / farthest for value in raw]
        self._activation = activation
        (forward, turn), = sim.true_twist.tolist()
        true_left, true_right = (wheel / top for wheel in wheels_from_twist(forward, turn, self.model))
        speed = 0.5 * (true_left + true_right)
        reward = speed * (1.0 - math.sqrt(0.5 * abs(true_left - true_right))) * (1.0 - max(activation))
        wheels = [wheel / top for wheel in sim.wheel_speeds[0].tolist()]
        return np.array(activation + wheels, dtype=np.float32), reward, self.steps >= self.episode_steps

    @property
    def last_activation(self) -> np.ndarray:
        """(count, 8) IR activations of the last observations."""
        return np.asarray(self._activation, dtype=float).reshape(self.count, 8)

    def _observe(self) -> np.ndarray:
        raw = self.sim.ir_raw
        if self.noise:
            normals = self._normals
            for rng, row in zip(self.rngs, normals):
                rng.standard_normal(out=row)
            raw = raw * (1.0 + np.interp(raw, self._noise_raws, self._noise_sigmas) * normals)
        self._activation = activations(raw, self.model)
        return observations(self._activation, self.sim.wheel_speeds, self.model)


def reach(model: RobotModel) -> float:
    """m: the farthest an IR sensor tells an obstacle from nothing, the distance of the raw value FREE_READING_SIGMAS
    noise deviations above the far end of the table (0.0673 m on the e-puck: raw 77.1)."""
    _, far_raw, far_noise = model.ir_table[-1]
    return float(distance_from_raw(far_raw * (1.0 + FREE_READING_SIGMAS * far_noise), model.ir_table))


def activations(raw: np.ndarray, model: RobotModel) -> np.ndarray:
    """Raw IR values (N, 8) as activations in [0, 1] (N, 8): 1 - d / reach, d the distance the value stands for on
    the lookup table (its inverse), reach the farthest a sensor tells something from nothing (`reach`, 0.0673 m).
    0 when nothing is seen, 0.70 at 2 cm, 0.85 at 1 cm, 1 touching.

    Floreano and Mondada normalised each Khepera sensor on its own range, 0 to 1023. The Khepera's value falls
    about linearly with distance over its 5 cm reach (Webots' Khepera1.proto models it as 1023 at 0 m to 0 at
    0.05 m) and reads about 0 with nothing in front, so their i is the share of the sensor's reach an obstacle has
    closed: 0.6 at 2 cm. The e-puck's raw value is nothing like linear (4095 touching, 384 at 2 cm, 67 at 7 cm:
    (raw - 67) / (4095 - 67) is 0.08 at 2 cm), so the same meaning on the e-puck's range is the distance read back
    through the e-puck's own table; and its free sensor reads 67 with 4.9 % noise, so values within the noise of
    nothing (the behaviours' "nothing seen", behaviours.base) read 0, as the Khepera's free sensor does, rather than
    a flicker every step that a network would have to learn to ignore.
    """
    table = model.ir_table
    farthest = reach(model)
    return 1.0 - np.minimum(np.maximum(distance_from_raw(raw, table), 0.0), farthest) / farthest


def observations(activation: np.ndarray, wheel_speeds: np.ndarray, model: RobotModel) -> np.ndarray:
    """(N, 10) float32: the IR activations and the applied wheel speeds (rad/s) as fractions of the maximum."""
    observation = np.empty((len(activation), OBSERVATION_SIZE), dtype=np.float32)
    observation[:, :8] = activation
    observation[:, 8:] = wheel_speeds / model.max_wheel_speed
    return observation


def check_actions(actions: object, shape: tuple[int, ...]) -> np.ndarray:
    """`actions` as a float array of `shape` ((2,) or (count, 2)), each value clipped to the action space's [-1, 1]
    (the wheels' own clamp: 5 or 1e308 is full speed); CommandError (a ValueError) saying what is wrong for another
    shape, a NaN or an infinity, or a number no float holds (10**400)."""
    try:
        array = np.asarray(actions, dtype=float)
    except OverflowError:
        raise CommandError(f'action rejected: wheel speeds must be finite numbers, got one too large for a float '
                           f'(shape {shape} expected)') from None
    except (TypeError, ValueError):
        raise CommandError(f'action rejected: expected wheel speeds (fractions of the maximum) of shape {shape}, '
                           f'got {actions!r}') from None
    if array.shape != shape:
        raise CommandError(f'action rejected: expected shape {shape} (left, right wheel speeds as fractions of the '
                           f'maximum), got shape {array.shape}')
    if len(shape) == 1:   # one action: plain floats, no NumPy call
        left, right = array.tolist()
        if math.isfinite(left) and math.isfinite(right):
            return array if -1.0 <= left <= 1.0 and -1.0 <= right <= 1.0 else np.clip(array, -1.0, 1.0)
    if not np.isfinite(array).all():
        rows = array.reshape(-1, 2)
        bad = int(np.flatnonzero(~np.isfinite(rows).all(axis=1))[0])
        where = f' in world {bad}' if len(shape) == 2 else ''
        raise CommandError(f'action rejected: wheel speeds must be finite numbers, got {rows[bad].tolist()}{where}')
    return np.clip(array, -1.0, 1.0)
