"""The run itself: start every process at once, wait until the graph shows them connected, resume the
simulator, watch until the end, stop everything in order and print one summary (or only the error)."""
from __future__ import annotations

import argparse
import math
import os
import signal
import sys
import threading
import time
from collections.abc import Callable

from epuck_ros.bag.gaps import bag_gaps
from epuck_ros.bag.reader import Bag, BagError
from epuck_ros.bringup import summary, tables
from epuck_ros.bringup.cli import FOXGLOVE_HOST, Plan, parse_args, ros_domain
from epuck_ros.bringup.monitor import RunMonitor, samples_missing
from epuck_ros.bringup.processes import Child, Children, executable, say
from epuck_ros.ros.announcements import Announcement
from epuck_ros.foxglove.address import NODE_NAME as FOXGLOVE_NODE

STOP_ORDER = ('controller', 'view', 'foxglove', 'record', 'sim')
"""Controllers stop first (a behaviour commands a stop as it ends) while the simulator still runs and the recorder
still writes; the recorder closes its bag before the simulator goes."""
READY_TIMEOUT = 60.0
"""Wall seconds for every process to show up connected in the graph, counted from the last time the graph grew
while they started (`new_high`): a swarm's start-up takes minutes on a loaded machine, each of its thousands of
endpoints a step, while a start-up that stopped growing is stuck."""
SETTLE_TIME = 0.5
"""Without lockstep only: wall seconds between seeing the controllers in the graph and resuming, for the
simulator's publishers to match them (the graph does not show matching). In lockstep the simulator's first step
waits until it sees as many controllers as `bringup` saw (`lockstep_controllers`), and it re-sends that step
until every controller has answered, so no wait is needed there."""
CATCH_UP_TIMEOUT = 5.0
"""Wall seconds the end of a run waits for ground-truth samples still on their way."""
PAUSE_TIMEOUT = 5.0
"""Wall seconds the end of a run waits for the simulator to accept paused:=true."""
LOAD_STRETCH = 4.0
"""At most this many times the simulator's discovery window is watched, on a machine loaded beyond its cores."""
GRAPH_CHECK_PERIOD = 0.5
"""Wall seconds between two looks for another simulator during the run."""
WATCH_SLICE = 0.02
"""Wall seconds between two looks at the children and the graph while watching (`RunMonitor.spin`)."""


def new_high(best: tuple[int, ...] | None, now: tuple[int, ...]) -> tuple[int, ...] | None:
    """The highest figures so far if `now` beats `best` in one of them, else None. Only a new high is progress: a
    graph that loses a participant and finds it again (its lease ran out on a loaded machine) goes down and up
    again without getting anywhere, and counting every change kept a stuck 500-robot start-up waiting for ever."""
    if best is None:
        return now
    high = tuple(max(old, new) for old, new in zip(best, now))
    return high if high != best else None


class RunFailed(Exception):
    """The run could not start or had to end early; the message says why (and which child, if one died)."""

    def __init__(self, message: str, child: Child | None = None) -> None:
        super().__init__(message)
        self.child = child


class DomainTaken(RunFailed):
    """Another simulator runs on this ROS domain: nothing was started (exit 2), the other run goes on untouched."""


class Supervisor:
    """Starts the processes and watches them: a child that dies, or another simulator, ends the run."""

    def __init__(self, args: argparse.Namespace, plan: Plan, children: Children) -> None:
        self.args = args
        self.plan = plan
        self.monitor: RunMonitor
        self.children = children
        self.stop_requested = threading.Event()
        self.resumed_at: float | None = None
        self.ended_at: float | None = None
        self.controller_ended = False
        # With ROS security on, an enclave must exist in the keystore: then the simulator keeps the default one.
        secure = os.environ.get('ROS_SECURITY_ENABLE', '').lower() == 'true'
        self.sim_enclave = '' if secure else f'/epuck_ros_bringup_{os.getpid()}'

    def ros_args(self, params: list[str], sim_time: bool = True, namespace: str = '') -> list[str]:
        args = ['--ros-args', *(['-p', 'use_sim_time:=true'] if sim_time else [])]
        args += [arg for p in params for arg in ('-p', p)]
        namespace = '/'.join(part for part in (self.args.namespace.strip('/'), namespace) if part)
        return args + (['-r', f'__ns:=/{namespace}'] if namespace else [])

    def start_all(self) -> None:
        """Every process at once: the simulator starts paused, so nothing happens before all are connected."""
        plan, start = self.plan, self.children.start
        # The clock source never listens to itself: no use_sim_time for the simulator. Its enclave (a plain name
        # without ROS security) is how the graph tells it from any other node called sim.
        start('sim', 'sim', [executable('sim'), *self.ros_args(plan.sim_params, sim_time=False),
                             *(['--enclave', self.sim_enclave] if self.sim_enclave else [])])
        if plan.record_dir is not None:
            start('record', 'record', [executable('record'), '-o', str(plan.record_dir), '--compression',
                                       self.args.record_compression, *self.ros_args([])])
        command = list(plan.controller_command)
        if plan.controller_kind != 'rclpy':
            command[0] = executable(command[0])
        robot_ns = self.args.robot if plan.controller_kind == 'rclpy' and self.args.robot else ''
        for robot in plan.script_robots:
            start('controller', f'{robot}:{plan.controller}',
                  [*command, '--robot', robot, *self.ros_args(plan.controller_params)])
        if not plan.script_robots:
            start('controller', plan.controller, [*command, *self.ros_args(plan.controller_params, namespace=robot_ns)])
        if self.args.view:
            start('view', 'view', [executable('view'), *self.ros_args(plan.view_params)])
        if plan.foxglove_port is not None:
            start('foxglove', 'foxglove', [executable('foxglove'), '--port', str(plan.foxglove_port),
                                           *self.ros_args([], sim_time=False)])

    def watch(self, done: Callable[[], bool], timeout: float, what: Callable[[], str],
              until_sim_time: float = math.inf, progress: Callable[[], tuple[int, ...]] | None = None) -> None:
        """Spin until `done()` or a stop request; RunFailed on a child's death, another simulator or the timeout:
        `timeout` wall seconds, or with `progress`, that long without a new high of `progress()` (`new_high`,
        looked at every GRAPH_CHECK_PERIOD). `done()` is looked at every WATCH_SLICE, and at once when `/clock`
        reaches `until_sim_time`."""
        deadline = time.monotonic() + timeout
        next_check = 0.0
        best: tuple[int, ...] | None = None
        while not self.stop_requested.is_set() and not done():
            self.monitor.spin(WATCH_SLICE, until_sim_time)
            dead = self.children.dead()
            if dead is not None:
                if dead.role == 'controller' and dead.process.returncode == 0 and self.plan.controller_kind != \
                        'behaviour' and self.resumed_at is not None:
                    self.controller_ended = True  # a script that ends is a run that ends
                    return
                raise RunFailed(dead.failure(), dead)
            if time.monotonic() >= next_check:
                self.refuse_other_simulators()
                high = new_high(best, progress()) if progress is not None else None
                if high is not None:
                    best, deadline = high, time.monotonic() + timeout
                next_check = time.monotonic() + GRAPH_CHECK_PERIOD
            if self.monitor.world_error:
                raise RunFailed(f'cannot read the simulator\'s world: {self.monitor.world_error}')
            if time.monotonic() > deadline:
                raise RunFailed(f'{what()}: the ROS graph got no further for {timeout:.0f} s' if progress else
                                f'{what()} within {timeout:.0f} s')

    def own_announcement(self) -> Announcement | None:
        """Our simulator's announcement, once heard: its start time orders it among the others."""
        return next((a for a in self.monitor.announcements if a.is_process(self._sim().process.pid)), None)

    def sim_ended(self) -> bool:
        return self._sim().process.poll() is not None

    def _sim(self) -> Child:
        return next(child for child in self.children.started if child.role == 'sim')

    def older_simulators(self) -> list[str]:
        """Simulators that announced a start before ours: ours refuses to run when it hears them (perhaps only
        after the resume, when discovery is slow), so the run cannot be ours."""
        own = self.own_announcement()
        return [other.describe() for other in sorted(self.monitor.announcements)
                if own is not None and other < own]

    def refuse_other_simulators(self) -> None:
        """Our simulator is paused (silent) until the resume, so a /clock message before it is another's; after it,
        two /clock publishers, `world` publishers or nodes named sim are two simulators; and so is an older
        simulator's announcement, at any time."""
        monitor = self.monitor
        clocks, sims, older = monitor.clock_sources(), monitor.other_simulators(), self.older_simulators()
        ticking = self.resumed_at is None and monitor.clock_messages > 0
        if ticking or sims or older or len(clocks) > 1 or monitor.world_sources() > 1:
            seen = ', '.join(older or sorted(set(clocks) | set(sims))) or '/clock ticking'
            raise RunFailed(f'another simulator or /clock source is running on this ROS domain ({seen}; '
                            f'{ros_domain()}): stop it, or run with another ROS_DOMAIN_ID')

    def refuse_a_taken_domain(self) -> None:
        """Before any child starts: watch the domain for the simulator's discovery window and refuse (DomainTaken)
        if another simulator is there: its /clock ticking or published, its announcement, a node called sim.
        Started after the check, our controller once drove the other run's robot before our simulator refused."""
        monitor, window = self.monitor, discovery_window()
        while not self.stop_requested.is_set():
            monitor.spin(WATCH_SLICE)
            found = sorted(set(monitor.clock_sources()) | set(monitor.other_simulators())) or \
                [a.describe() for a in monitor.announcements] or \
                (['/clock ticking'] if monitor.clock_messages else [])
            if found:
                raise DomainTaken(f'another simulator is running on this ROS domain ({", ".join(found)}; '
                                  f'{ros_domain()}): nothing was started; stop it, or run with another ROS_DOMAIN_ID')
            if time.monotonic() >= monitor.created + window:
                return

    def connected(self) -> bool:
        """Everything the run needs is in the graph: sim up, recorder subscribed, controllers connected, view up."""
        monitor = self.monitor
        if monitor.sim_missing() or self.own_announcement() is None:
            return False
        if self.plan.record_dir is not None and not (monitor.recorder_subscribed() and monitor.recorder_heard()):
            return False
        if self.args.view and not monitor.view_serving():
            return False
        if self.plan.foxglove_port is not None and not self.foxglove_serving():
            return False
        robots = monitor.world.names
        wanted = self.plan.robots_to_drive
        if wanted == 'any':
            return any(monitor.controllers(robot) for robot in robots)
        if wanted != 'all':
            missing = [robot for robot in wanted if robot not in robots]
            if missing:
                raise RunFailed(f'--robot {missing[0]}: the simulator has no such robot (robots: {", ".join(robots)})')
            robots = wanted
        return all(monitor.controllers(robot) for robot in robots)

    def foxglove_serving(self) -> bool:
        """The bridge's node reads /clock once its server listens (it binds the port before it joins ROS)."""
        return any(info.node_name == FOXGLOVE_NODE for info in self.monitor.node.get_subscriptions_info_by_topic(
            '/clock'))

    def waiting_for(self) -> str:
        """What is still missing, for the timeout message."""
        monitor = self.monitor
        missing = monitor.sim_missing() or ('' if self.own_announcement() else 'has not announced itself')
        if missing:
            return f'the simulator did not come up (it {missing})'
        if self.plan.record_dir is not None and not monitor.recorder_subscribed():
            return 'the recorder did not subscribe to the simulator\'s topics'
        if self.plan.record_dir is not None and not monitor.recorder_heard():
            return 'the recorder did not hear from the controllers (their declarations did not reach it)'
        if self.args.view and not monitor.view_serving():
            return 'the view did not come up'
        if self.plan.foxglove_port is not None and not self.foxglove_serving():
            return 'the Foxglove bridge did not come up'
        return f'{self.plan.controller} did not connect to every robot it drives (no wheel_cmd/cmd_vel publisher)'

    def run(self) -> None:
        """Start everything, resume the simulation, and watch until the end; RunFailed says what went wrong."""
        args, plan = self.args, self.plan
        # Our DDS participant first: created before the children's, it hears their first announcements (one
        # created after them waited for their next periodic announcement, ~3 s later: measured with
        # benchmarks/bench_startup.py). Then the children, whose own start-up is the longest part.
        self.monitor = RunMonitor(args.namespace, self.sim_enclave, follow_robots=plan.record_dir is None)
        self.refuse_a_taken_domain()
        if self.stop_requested.is_set():
            return
        self.start_all()
        self.watch(self.connected, READY_TIMEOUT, self.waiting_for, progress=self.monitor.graph_progress)
        if self.stop_requested.is_set():
            return
        if not args.lockstep:
            time.sleep(SETTLE_TIME)
        # Our simulator skips its own discovery window (cli passes discovery_window:=0): this process has watched the
        # domain since before it started the simulator, and does so for at least as long before the resume.
        watched = float(tables.sim_default('discovery_window'))
        self.watch(lambda: time.monotonic() >= self.monitor.created + watched, READY_TIMEOUT, lambda: '')
        self.refuse_other_simulators()
        self.resumed_at = time.monotonic()  # the request's: the simulator may step before its answer is back
        # In lockstep, the controllers this process sees: the simulator's first step waits until it sees them too.
        seen = sum(1 for robot in self.monitor.world.names if self.monitor.controllers(robot)) \
            if args.lockstep else None
        if not self.monitor.set_paused(False, READY_TIMEOUT, controllers=seen):
            raise RunFailed('the simulator did not accept paused:=false')
        robots = self.monitor.world.names
        pace = f'real-time factor {args.real_time_factor:g}' if args.real_time_factor else 'as fast as possible'
        say(f'[bringup] running {plan.controller}' + (f' on {len(robots)} robots' if len(robots) > 1 else '') +
            (f' for {args.duration:g} simulated s' if args.duration else ' until Ctrl-C') +
            f' ({"lockstep" if args.lockstep else "no lockstep"}, {pace})')
        if plan.view_url:
            say(f'[bringup] view: {plan.view_url}  (open it in a browser)')
        if plan.foxglove_port:
            say(f'[bringup] foxglove: ws://{FOXGLOVE_HOST}:{plan.foxglove_port}  (in Foxglove: Open connection, '
                'Foxglove WebSocket; layout: docs/foxglove_layout.json)')
        # The simulator pauses itself at exactly `pause_at` = duration: the run ends on that very step.
        try:
            self.watch(lambda: bool(args.duration) and self.monitor.sim_time >= args.duration - 1e-6,
                       math.inf, lambda: '', args.duration or math.inf)
        finally:
            self.ended_at = time.monotonic()
        if args.duration and not self.stop_requested.is_set() and not self.controller_ended:
            self.check_the_end(args.duration)

    def check_the_end(self, duration: float) -> None:
        """The time that ended the run was our simulator's: it pauses itself on the first step at or after
        `duration`, so a later `/clock`, an older simulator or its death means another clock source ran the run."""
        self.refuse_other_simulators()
        dead = self.children.dead()
        if dead is not None:
            raise RunFailed(dead.failure(), dead)
        if self.monitor.sim_time > duration + _time_step(self.plan) + 1e-6:
            raise RunFailed(f'/clock reached {self.monitor.sim_time:.3f} s, past the {duration:g} s our simulator '
                            f'pauses at: another /clock source is running on this ROS domain ({ros_domain()}): stop '
                            'it, or run with another ROS_DOMAIN_ID')


STALL_NOTE = 0.5
"""Wall seconds without a new simulated instant from which the summary says so (a step takes well under 1 ms)."""


def report(supervisor: Supervisor, sim_time: float, wall_time: float) -> list[str]:
    """The summary lines: time and speed (from the resume on, and from the first step on), then each robot's
    distance and contacts (from the bag if the run was recorded, else from the samples received: the same
    computation either way)."""
    plan, monitor = supervisor.plan, supervisor.monitor
    speed = f'{sim_time / wall_time:.1f}x real time' if wall_time > 0 else 'no wall time'
    line = f'[bringup] simulated {sim_time:.2f} s in {wall_time:.1f} s wall ({speed})'
    stepping = monitor.stepping_speed()
    if stepping is not None and supervisor.resumed_at is not None:
        line += (f'; {stepping:.1f}x real time from the first step, which came '
                 f'{monitor.first_tick[0] - supervisor.resumed_at:.2f} s after the resume')
    head = [line]
    notes = []
    stall, at = monitor.longest_stall
    if stall >= STALL_NOTE:
        head.append(f'[bringup] note: simulated time stood still for {stall:.1f} s wall at t={at:.3f} s (lockstep '
                    f'waiting for a controller\'s answer, or a busy machine: see the lines above)')
    integrity = monitor.integrity
    head.append(f'[bringup] {integrity.message}' if integrity is not None else
                '[bringup] reproducible: unknown (the simulator\'s lockstep_status never came)')
    if plan.record_dir is not None:
        try:
            figures, motions = summary.from_bag(plan.record_dir)
        except (BagError, OSError) as error:
            return head + [f'[bringup] cannot summarise the bag: {error}']
        notes.append(f'[bringup] recorded to {plan.record_dir} (bag summary {plan.record_dir} says more)')
        notes += [f'[bringup] note: the recording lost {line}' for line in recording_losses(plan.record_dir)]
    elif monitor.tally is not None:
        figures = monitor.tally.figures
        motions = summary.motions_of({track.label: track.samples for track in monitor.tracks.values()}, monitor.world)
        time_step = _time_step(plan)
        lost = sum(samples_missing(track, time_step, sim_time) for track in monitor.tracks.values())
        if lost:
            notes.append(f'[bringup] note: {lost} ground-truth samples did not arrive; distances are from the '
                         f'others (record the run for exact figures)')
    else:
        return head
    return head + [f'[bringup] {line}' for line in summary.lines(figures, motions)] + notes


def recording_losses(bag_dir: os.PathLike | str) -> list[str]:
    """What the bag is missing, by the recorder's own check (`bag_gaps`, what `record` logs at its end and `bag info`
    lists): stamp gaps of the periodic topics, steps without an answer."""
    try:
        with Bag(bag_dir) as bag:
            return [gaps.describe() for gaps in bag_gaps(bag)[1]]
    except BagError as error:
        return [f'(the bag cannot be checked: {error})']


def discovery_window() -> float:
    """Wall seconds `bringup` watches the domain for another simulator before it starts anything: the simulator's
    discovery window (participants announce every 0.5 s), stretched by the load per core when it is over 1, up to
    LOAD_STRETCH times: a participant starved of CPU announces and answers late. A second `bringup` started beside
    four test processes and a busy loop per core heard the first run's simulator only after it had started its
    children (the later check refused it then, exit 1, not 2)."""
    load = os.getloadavg()[0] / (os.cpu_count() or 1)
    return float(tables.sim_default('discovery_window')) * min(LOAD_STRETCH, max(1.0, load))


def _time_step(plan: Plan) -> float:
    for assignment in plan.sim_params:
        name, _, value = assignment.partition(':=')
        if name == 'time_step':
            return float(value)
    return float(tables.sim_default('time_step'))


def run(args: argparse.Namespace, plan: Plan) -> int:
    say(f'[bringup] {ros_domain()}')
    children = Children()
    supervisor = Supervisor(args, plan, children)
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: supervisor.stop_requested.set())
    failure, failed_child, refused = '', None, False
    try:
        supervisor.run()
    except RunFailed as error:
        failure, failed_child, refused = str(error), error.child, isinstance(error, DomainTaken)
    except FileNotFoundError as error:  # an executable is missing from the installation
        failure = str(error)
    finally:
        # The figures are those of the run, not of the moments the simulator keeps going while stopping.
        started, ended = supervisor.resumed_at, supervisor.ended_at or time.monotonic()
        monitor = getattr(supervisor, 'monitor', None)
        if started is not None and not failure:
            # Paused first: a simulator left running without its controller (lockstep has nobody to wait for)
            # would flood the recorder, which must take all it holds before it can close the bag.
            if not supervisor.sim_ended():
                monitor.set_paused(True, PAUSE_TIMEOUT)
            monitor.catch_up(CATCH_UP_TIMEOUT)
        sim_time = monitor.sim_time if monitor is not None else 0.0
        script = next((c for c in children.started if c.role == 'controller'), None) \
            if plan.controller_kind == 'rclpy' else None
        problems, notes = children.stop(STOP_ORDER, failed_child, lenient=script)
        lines = report(supervisor, sim_time, ended - started) if started is not None and not failure else []
        if monitor is not None:
            monitor.close()
    for signum in (signal.SIGINT, signal.SIGTERM):  # all is stopped: a late Ctrl-C must not change the exit code
        signal.signal(signum, signal.SIG_IGN)
    for line in lines + [f'[bringup] note: {note}' for note in notes]:
        say(line)
    for problem in ([failure] if failure else []) + problems:
        say(f'[bringup] error: {problem}', sys.stderr)
    return 2 if refused else 1 if failure or problems else 0


def main(argv: list[str] | None = None) -> None:
    args, plan = parse_args(sys.argv[1:] if argv is None else argv)
    sys.exit(run(args, plan))
