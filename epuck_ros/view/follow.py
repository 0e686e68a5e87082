"""Which topics the view reads, without ROS: what the pages draw, read the cheapest way the simulator offers it.

Every subscriber costs the simulator a send per step, and from `TOPICS_ON_DEMAND_FROM` robots (`ros.on_demand`) a
robot's topics are made only once someone reads them: a view that read every robot's own topics made a
thousand-robot simulator make thousands of topics and send each of them every step. So:
- nothing while no page is open (the readings kept meanwhile are what a page opened later starts from);
- every robot's step (ground truth, odometry, wheel speeds, raw IR) from the one `swarm/observation` message per step
  when the simulator publishes it (it does with several robots); else (one robot, a bag recorded without the swarm
  topic) from each robot's own `ground_truth` and `ir_raw` (the eight `proximity` Ranges of a bag recorded before
  `ir_raw` existed, until an `ir_raw` arrives), of the robots whose `ground_truth` has a publisher, so a
  thousand-robot simulator is never made to make them;
- of the robots a page shows in detail: the camera, and on their own topics odometry and wheel speeds when the step
  does not come in the swarm message;
- the latched contact counts and LEDs (a message only when they change) of every robot when `latched_of_all`, else
  of the robots shown in detail only.
"""
from __future__ import annotations

from collections.abc import Collection

from epuck_ros.swarm_messages import OBSERVATION_TOPIC

SWARM = ''
"""The robot of the swarm topic's key: it is no robot's own."""
STEP_TOPICS = ('ground_truth', 'ir_raw', 'proximity')
"""A robot's own topics that carry what the canvas draws of it each step."""
DETAIL_TOPICS = ('odom', 'joint_states')
"""A robot's own topics the detail panel shows, when the step is not read from the swarm topic."""
CAMERA_TOPIC = 'camera/image_raw'
LATCHED_TOPICS = ('collisions', 'leds')

Topic = tuple[str, str]
"""(robot, topic under the robot); (SWARM, OBSERVATION_TOPIC) for the swarm topic."""


def wanted_topics(robots: Collection[str], pages_open: bool, detailed: Collection[str], swarm_published: bool,
                  published: Collection[str], ir_raw_seen: Collection[str], latched_of_all: bool) -> set[Topic]:
    """The topics to read now. `robots`: the world's; `detailed`: those pages show in detail; `swarm_published`: the
    graph shows a publisher of the swarm topic; `published`: the robots whose own `ground_truth` has a publisher;
    `ir_raw_seen`: the robots an `ir_raw` came from."""
    if not pages_open:
        return set()
    detailed = set(detailed) & set(robots)
    wanted = {(robot, CAMERA_TOPIC) for robot in detailed}
    wanted |= {(robot, topic) for robot in (robots if latched_of_all else detailed) for topic in LATCHED_TOPICS}
    if swarm_published:
        return wanted | {(SWARM, OBSERVATION_TOPIC)}
    for robot in set(robots) & set(published):
        wanted |= {(robot, topic) for topic in STEP_TOPICS if topic != 'proximity' or robot not in ir_raw_seen}
    return wanted | {(robot, topic) for robot in detailed for topic in DETAIL_TOPICS}
