"""What the simulator says about its lockstep: the lines of a step that waits, and whether the run is reproducible
(epuck_ros/integrity.py) on its latched `lockstep_status`, so a reader that comes late (bringup's summary, the
fixture, a recorder) gets the verdict. The `Lockstep`'s callbacks, in words; `now()` gives the simulated time."""
from __future__ import annotations

from collections.abc import Callable, Sequence

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from rclpy.node import Node

from epuck_ros.integrity import STATUS_TOPIC, Integrity
from epuck_ros.lockstep import HOW_TO_DECLARE, OWN_RATE_WAIT, Answer, Controller
from epuck_ros.ros.qos import LATCHED
from epuck_ros.ros.robot_ports import quiet_publisher


class LockstepReport:
    """The lockstep's log lines and `lockstep_status` of a simulator of robots `names`."""

    def __init__(self, node: Node, names: Sequence[str], integrity: Integrity, timeout: float,
                 now: Callable[[], float]) -> None:
        self._logger, self._names, self._timeout, self._now = node.get_logger(), names, timeout, now
        self._publisher = quiet_publisher(node, DiagnosticStatus, STATUS_TOPIC, LATCHED)
        self.integrity = integrity
        self._publish(integrity)

    def controllers(self, required: int, driven: Sequence[int]) -> None:
        connected = ', '.join(self._names[robot] for robot in driven) or 'none'
        self._logger.info(f'lockstep: waiting for {required} controller{"s" * (required != 1)} before the first '
                          f'step (lockstep_controllers); connected: {connected}')

    def resend(self, back: Sequence[int]) -> None:
        if back:
            self._logger.info(f'lockstep: the controller of {self._named(back)} is back on the graph: sending '
                              f't={self._now():.3f} s again')
        else:
            self._logger.info(f'lockstep: no first answer to t={self._now():.3f} s yet, sending it again')

    def stall(self, robots: Sequence[int], waited: float, gone: Sequence[int]) -> None:
        limit = f'lockstep_timeout {self._timeout:g} s' if self._timeout else 'lockstep_timeout 0: as long as it takes'
        left = f'; the controller of {self._named(gone)} left the graph (ended, or stopped, frozen or crashed ' \
               f'without a word): the step is sent again when one is back' if gone else ''
        self._logger.warning(f'lockstep: t={self._now():.3f} s has waited {waited:.0f} s for the answer of '
                             f'{self._named(robots)} ({limit}){left}')

    def leave(self, robot: int) -> None:
        self._logger.info(f'lockstep: the controller of {self._names[robot]} left, declared at its own rate: no '
                          f'longer waited for (t={self._now():.3f} s)')

    def timeout(self, robots: Sequence[int]) -> None:
        self.broken(f't={self._now():.3f} s went on without the answer of {self._named(robots)} '
                    f'(lockstep_timeout {self._timeout:g} s)')

    def free(self, robot: int, why: Answer | Controller) -> None:
        """Say once why lockstep no longer waits for this robot's controller, and what to do."""
        declare = f'; {HOW_TO_DECLARE}' if why is Answer.SILENT else ''
        self.broken(f'the controller of {self._names[robot]} {why.value}: it is taken to answer at its own rate '
                    f'(each step now waits at most {OWN_RATE_WAIT * 1000:g} ms for it); a lockstep controller '
                    f'answers each step naming it (wheel_cmd labelled stamp=SEC.NANOSEC, or TwistStamped with '
                    f'cmd_vel_stamped:=true){declare}')

    def conflict(self, robot: int, step: float, detail: str, publishers: str) -> None:
        """Two different answers to one step (`detail`: which): the first drove, and which came first was a matter
        of timing."""
        self.broken(f'{self._names[robot]} got two different answers to t={step:.3f} s ({detail}): a second '
                    f'controller answers its steps, or one answers a step twice; the first drove. Publishers of its '
                    f'commands: {publishers}')

    def beside(self, robot: int, topic: str) -> None:
        self.broken(f'a command that names no step drove {self._names[robot]} beside its lockstep controller '
                    f'(another publisher on {topic}, or the controller stopping)')

    def broken(self, reason: str) -> None:
        """The run is no longer reproducible: said once, with the first reason, on the log and lockstep_status."""
        if self.integrity.reproducible:
            now = self._now()
            self._logger.warning(f'lockstep: not reproducible from t={now:.3f} s: {reason}')
            self._publish(Integrity(False, reason, now))

    def _publish(self, integrity: Integrity) -> None:
        self.integrity = integrity
        level, name, message, values = integrity.fields()
        self._publisher.publish(DiagnosticStatus(level=bytes([level]), name=name, message=message,
                                                 values=[KeyValue(key=key, value=value) for key, value in values]))

    def _named(self, robots: Sequence[int]) -> str:
        names = [self._names[robot] for robot in robots]
        return ', '.join(names[:5]) + (f' and {len(names) - 5} more' if len(names) > 5 else '')
