"""Line following with an obstacle by-pass, after Webots' own e-puck demo, with its thresholds.

Webots ships this behaviour as projects/robots/gctronic/e-puck/controllers/e-puck_line_demo/e-puck_line_demo.c
(by Jean-Christophe Zufferey, EPFL-LIS). This is the same behaviour retold in Python, unchanged in its numbers, so
that a program tuned on Webots' ground sensors can be run here as it is:

- White floor and black line as Webots reads them: a ground value below 500 is the line (LEM_THRESHOLD), two
  ground values averaging above 800 are off it (LLM_THRESHOLD), and 900 is the white the re-entry steers by
  (GS_WHITE). Webots' e-puck reads about 843 on its line worlds' white floor and 300 on black.
- Five small modules, each later one overriding the earlier ones when it has something to say (subsumption):
  follow: forward at 200 motor steps/s, the wheel on the darker side slowed by 0.4 x the difference of the outer
  ground values; avoid: a front IR value more than 100 above its 300 offset means an obstacle, on the side whose
  front sensors sum higher, and the robot turns away from it; leave: from when avoiding starts until the line is
  behind (the two ground values on the obstacle's side averaging above 800) the pull towards the obstacle is held
  off, then re-entry is armed; pull: while an obstacle side is known, a turn towards it (so the robot goes around
  the obstacle); enter: once armed, it looks for the line on the far side (a value below 500), then steers onto it
  until the other outer sensor has crossed it (black, then white), and clears the obstacle side.
- Speeds are e-puck motor steps per second, 0.00628 rad/s each, as in the demo.

On a track without obstacles only `follow` acts. Run: bringup --controller line_demo.py --world line_track.yaml
"""
from controller import Robot

ON_LINE = 500          # a ground value below this is the black line (LEM_THRESHOLD)
OFF_LINE = 800         # two ground values averaging above this are white floor (LLM_THRESHOLD)
WHITE = 900            # the white the re-entry steers by (GS_WHITE)
IR_OFFSET = 300        # taken off every IR value in simulation (PS_OFFSET_SIMULATION)
OBSTACLE = 100         # an IR value, less its offset, above this is an obstacle (OAM_OBST_THRESHOLD)
RAD_PER_STEP = 0.00628  # rad/s of the wheel per motor step per second

FOLLOW_SPEED, FOLLOW_GAIN = 200, 0.4
AVOID_SPEED, AVOID_MAX_TURN = 150, 600
AVOID_GAINS = ((2, 0.2), (1, 0.9), (0, 1.2))   # (right sensor, gain): side 90, 45 and 0 degrees; left: 7 - sensor
PULL_SPEED = 150
ENTER_SPEED, ENTER_GAIN = 100, 0.5
LEFT, RIGHT = 0, 1
GROUND_LEFT, GROUND_CENTRE, GROUND_RIGHT = 0, 1, 2
STANDBY, LOOKING, CROSSING, ARRIVED = range(4)


class Demo:
    """The demo's modules and their memory; `speeds` turns one step's readings into wheel speeds (steps/s)."""

    def __init__(self):
        self.avoiding, self.obstacle_side, self.forget_obstacle = False, None, False
        self.leaving, self.side_before, self.hold_pull = False, None, False
        self.entering, self.entry, self.arm_entry, self.far_was_black = False, STANDBY, False, False

    def speeds(self, ir, ground):
        left, right = self.follow(ground)
        avoid = self.avoid(ir)
        self.leave(ground)
        pull = self.pull()
        if self.hold_pull:
            pull = (0, 0)
        if self.avoiding or self.obstacle_side is not None:
            left, right = avoid[0] + pull[0], avoid[1] + pull[1]
        enter = self.enter(ground)
        return enter if self.entering else (left, right)

    def follow(self, ground):
        turn = FOLLOW_GAIN * (ground[GROUND_RIGHT] - ground[GROUND_LEFT])
        return int(FOLLOW_SPEED - turn), int(FOLLOW_SPEED + turn)

    def avoid(self, ir):
        if self.forget_obstacle:
            self.avoiding, self.obstacle_side = False, None
        self.forget_obstacle = False
        front = (ir[0], ir[1], ir[6], ir[7])
        if max(front) > OBSTACLE:
            self.avoiding = True
        if self.avoiding and self.obstacle_side is None:
            self.obstacle_side = RIGHT if ir[0] + ir[1] > ir[6] + ir[7] else LEFT
        if not self.avoiding:
            return AVOID_SPEED, AVOID_SPEED
        if self.obstacle_side == LEFT:
            turn = -sum(int(gain * ir[7 - sensor]) for sensor, gain in AVOID_GAINS)
        else:
            turn = sum(int(gain * ir[sensor]) for sensor, gain in AVOID_GAINS)
        turn = max(-AVOID_MAX_TURN, min(AVOID_MAX_TURN, turn))
        return AVOID_SPEED - turn, AVOID_SPEED + turn

    def leave(self, ground):
        side = self.obstacle_side
        if not self.leaving and side is not None and self.side_before is None:
            self.leaving = True
        self.side_before = side
        if not self.leaving:
            return
        outer = GROUND_LEFT if side == LEFT else GROUND_RIGHT
        if (ground[GROUND_CENTRE] + ground[outer]) // 2 > OFF_LINE:   # the line is behind
            self.leaving, self.hold_pull, self.arm_entry = False, False, True
        else:
            self.hold_pull = True

    def pull(self):
        if self.obstacle_side == LEFT:
            return -PULL_SPEED, PULL_SPEED
        if self.obstacle_side == RIGHT:
            return PULL_SPEED, -PULL_SPEED
        return 0, 0

    def enter(self, ground):
        if self.arm_entry:
            self.entry = LOOKING
        self.arm_entry = False
        # the line is entered on the side away from the obstacle: `near` looks for it, `far` watches it pass
        towards, near, far = (RIGHT, GROUND_RIGHT, GROUND_LEFT) if self.obstacle_side == LEFT else \
            (LEFT, GROUND_LEFT, GROUND_RIGHT)
        speeds = [ENTER_SPEED, ENTER_SPEED]
        if self.entry == STANDBY:
            self.entering = False
        elif self.entry == LOOKING:
            if ground[near] < ON_LINE:
                self.entering, self.entry = True, CROSSING
                self.far_was_black = ground[far] < ON_LINE
        elif self.entry == CROSSING:
            far_black = ground[far] < ON_LINE
            if self.far_was_black and not far_black:   # the far sensor has crossed the line: stop on it
                self.entry, speeds = ARRIVED, [0, 0]
            else:
                self.far_was_black = far_black
                steer = ENTER_GAIN * (WHITE - ground[near])
                speeds[towards] = ENTER_SPEED - steer
                speeds[1 - towards] = ENTER_SPEED + steer
        else:   # ARRIVED: back to following; the obstacle is forgotten on the next step
            self.forget_obstacle, self.entering, self.entry = True, False, STANDBY
        return int(speeds[LEFT]), int(speeds[RIGHT])


robot = Robot()
step_ms = int(robot.getBasicTimeStep())
wheels = [robot.getDevice('left wheel motor'), robot.getDevice('right wheel motor')]
for wheel in wheels:
    wheel.setPosition(float('inf'))
    wheel.setVelocity(0.0)
proximity = [robot.getDevice(f'ps{i}') for i in range(8)]
floor = [robot.getDevice(f'gs{i}') for i in range(3)]
for sensor in proximity + floor:
    sensor.enable(step_ms)
demo = Demo()

while robot.step(step_ms) != -1:
    if floor[0].getValue() != floor[0].getValue():   # NaN: no reading before the first sampling period
        continue
    ir = [max(0, int(sensor.getValue()) - IR_OFFSET) for sensor in proximity]
    ground = [int(sensor.getValue()) for sensor in floor]   # the demo keeps them as unsigned shorts
    for wheel, speed in zip(wheels, demo.speeds(ir, ground)):
        wheel.setVelocity(RAD_PER_STEP * speed)
