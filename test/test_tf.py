"""TF and robot_description of the running simulator, through real subscribers in another process (REP 105).

tf2_ros is not on PyPI: the lookups compose the received transforms here (world -> odom -> base_link).
"""
from __future__ import annotations

import math
import subprocess
import time
from collections.abc import Callable

import pytest

from epuck_ros.bringup.processes import executable, interrupt
from epuck_ros.description import IMU_FRAME, sensor_frames, urdf
from epuck_ros.model import (GROUND_SENSOR_NAMES, GROUND_SENSOR_POSES, IMU_POSITION, SENSOR_HEIGHT, SENSOR_POSES,
                             RobotModel)

tf2_msgs = pytest.importorskip('tf2_msgs.msg', reason='tf2_msgs is not installed: run scripts/gen_tf2_msgs.sh')


class Listener:
    """/tf, /tf_static and robot_description topics, heard on the simulator's domain in a context of its own."""

    def __init__(self, domain: int, description_topics: list[str], imu_topic: str | None = None) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import Imu
        from std_msgs.msg import String
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain)
        self.node = rclpy.create_node('tf_listener', context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.dynamic: dict[str, object] = {}
        self.static: dict[str, object] = {}
        self.descriptions: dict[str, str] = {}
        self.imus: list[object] = []
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                             reliability=ReliabilityPolicy.RELIABLE)
        self.node.create_subscription(tf2_msgs.TFMessage, '/tf', lambda m: self._keep(self.dynamic, m), 100)
        self.node.create_subscription(tf2_msgs.TFMessage, '/tf_static', lambda m: self._keep(self.static, m), latched)
        for topic in description_topics:
            self.node.create_subscription(String, topic, lambda m, t=topic: self.descriptions.__setitem__(t, m.data),
                                          latched)
        if imu_topic:
            self.node.create_subscription(Imu, imu_topic, self.imus.append, 10)

    @staticmethod
    def _keep(frames: dict, msg: object) -> None:
        for transform in msg.transforms:
            frames[transform.child_frame_id] = transform

    def spin_until(self, condition: Callable[[], bool], what: str, timeout: float = 30.0) -> None:
        deadline = time.monotonic() + timeout
        while not condition():
            assert time.monotonic() < deadline, f'{what} within {timeout} s'
            self.executor.spin_once(timeout_sec=0.05)

    def spin_for(self, seconds: float) -> None:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)

    def close(self) -> None:
        self.node.destroy_node()
        self.context.try_shutdown()


def planar(transform: object) -> tuple[float, float, float]:
    t, q = transform.transform.translation, transform.transform.rotation
    return t.x, t.y, math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def compose(a: tuple[float, float, float], b: tuple[float, float, float]) -> tuple[float, float, float]:
    x, y, yaw = a
    return (x + b[0] * math.cos(yaw) - b[1] * math.sin(yaw), y + b[0] * math.sin(yaw) + b[1] * math.cos(yaw),
            math.remainder(yaw + b[2], math.tau))


def test_base_link_in_world_is_the_ground_truth_and_sensors_are_the_models(epuck_sim):
    """Also the fixture's ground truth and contact count, before and after the robot meets a wall."""
    sim = epuck_sim(robots=1, seed=1)   # one robot placed at a start pose off the origin, turned
    listener = Listener(sim.domain, ['/robot_description'], '/imu')
    controller = subprocess.Popen([executable('forward'), '--ros-args', '-p', 'use_sim_time:=true'], env=sim.env,
                                  stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        sim.wait_for_controller()
        listener.spin_until(lambda: 'odom' in listener.static and 'ps3' in listener.static
                            and '/robot_description' in listener.descriptions, 'the static tree and description')
        reached = 0.0   # the simulator looks for sense subscribers every 0.5 wall s: step on until it found ours
        while not listener.imus and reached < 1.9:   # (at least 0.1 wall s a step: 5.9 s, a dozen looks)
            reached = sim.run_until(reached + 0.01)
            listener.spin_for(0.1)
        now = sim.run_until(2.0)
        listener.spin_until(lambda: 'base_link' in listener.dynamic and _stamp(listener.dynamic['base_link']) >= now
                            - 1e-9, f'/tf of t={now}')
        listener.spin_until(lambda: listener.imus, 'imu messages')
        truth, contacts = sim.ground_truth(), sim.contacts()
        sim.run_until(15.0)   # on into the wall at x = -0.5 (its path misses the boxes): the fixture counts it
        truth_later, contacts_later = sim.ground_truth(), sim.contacts()
    finally:
        interrupt(controller, 10.0)
        listener.close()
    world_odom, odom_base = listener.static['odom'], listener.dynamic['base_link']
    assert (world_odom.header.frame_id, odom_base.header.frame_id) == ('world', 'odom')
    assert planar(world_odom) == pytest.approx(sim.start_poses[sim.names[0]], abs=1e-12)
    in_world = compose(planar(world_odom), planar(odom_base))
    assert math.dist(sim.start_poses[sim.names[0]][:2], truth[:2]) > 0.1 and contacts == 0, 'it drove freely'
    # odometry reads quantised encoders: within a few ticks (2π/1000 rad · 0.02 m each) of the ground truth
    assert in_world == pytest.approx(truth, abs=5e-4)
    ps3 = listener.static['ps3']
    assert ps3.header.frame_id == 'base_link'
    assert (*planar(ps3), ps3.transform.translation.z) == pytest.approx((*SENSOR_POSES[3], SENSOR_HEIGHT), abs=1e-12)
    assert listener.descriptions['/robot_description'] == urdf()
    for name, xyz in zip(GROUND_SENSOR_NAMES, GROUND_SENSOR_POSES.tolist()):   # x along the ray, straight down
        assert listener.static[name].header.frame_id == 'base_link'
        assert translation(listener.static[name]) == pytest.approx(xyz, abs=1e-15)
        assert rotation(listener.static[name]) == pytest.approx((0.0, math.sqrt(0.5), 0.0, math.sqrt(0.5)), abs=1e-15)
    imu = listener.static[IMU_FRAME]
    assert (imu.header.frame_id, translation(imu), rotation(imu)) == ('base_link', IMU_POSITION, (0.0, 0.0, 0.0, 1.0))
    assert listener.imus and {msg.header.frame_id for msg in listener.imus} == {IMU_FRAME}
    assert contacts_later == 1 and truth_later[0] == pytest.approx(-0.5 + RobotModel().body_radius, abs=1e-3)


def test_a_swarm_prefixes_frames_and_descriptions_by_robot(epuck_sim):
    sim = epuck_sim(robots=3)
    topics = [f'/{name}/robot_description' for name in sim.names]
    listener = Listener(sim.domain, topics)
    expected = {f'{name}/{frame}' for name in sim.names for frame in ['odom'] + [f.name for f in sensor_frames()]}
    try:
        listener.spin_until(lambda: expected <= set(listener.static) and len(listener.descriptions) == 3,
                            'every robot\'s static frames and description')
    finally:
        listener.close()
    for name in sim.names:
        assert listener.static[f'{name}/odom'].header.frame_id == 'world'
        assert planar(listener.static[f'{name}/odom']) == pytest.approx(sim.start_poses[name], abs=1e-12)
        assert listener.static[f'{name}/ps3'].header.frame_id == f'{name}/base_link'
        assert listener.descriptions[f'/{name}/robot_description'] == urdf(prefix=f'{name}/')


def translation(transform: object) -> tuple[float, float, float]:
    t = transform.transform.translation
    return t.x, t.y, t.z


def rotation(transform: object) -> tuple[float, float, float, float]:
    q = transform.transform.rotation
    return q.x, q.y, q.z, q.w


def _stamp(transform: object) -> float:
    return transform.header.stamp.sec + transform.header.stamp.nanosec * 1e-9
