"""A swarm through `bringup`: hundreds of robots, one `avoid --robots all` process, started and stopped in full.

Before: `bringup avoid --robots 200` in a 10 m arena ended "avoid did not stop within 10 s of SIGTERM and was
killed" (exit 1: the process destroyed its 200 nodes one by one), and from 250 robots on a loaded machine "the
simulator did not come up within 60 s" (the start-up outgrew a fixed time-out). The run is in lockstep, so what it
does does not depend on the machine's load; the waits are bounded, not timed."""
from __future__ import annotations

import re

from conftest import processes_in_this_domain

from epuck_ros.bringup.run import new_high
from epuck_ros.nodes.behaviour_nodes import FULL_NODES_UP_TO

ROBOTS = 200
ROW = re.compile(r'^\[bringup\] (epuck\d+): [\d.]+ m in ', re.MULTILINE)


def test_a_swarm_of_hundreds_starts_runs_and_every_child_stops_by_itself(launch, tmp_path):
    assert ROBOTS > FULL_NODES_UP_TO   # the swarm's way of making and ending nodes
    world = tmp_path / 'arena.yaml'
    world.write_text('arena: {size: [10.0, 10.0]}\n')
    run = launch('bringup', 'avoid', '--robots', str(ROBOTS), '--world', str(world), '--duration', '0.1',
                 '--real-time-factor', '0')
    assert run.proc.wait(timeout=600) == 0, run.output()[-3000:]
    output = run.output()
    assert f'[bringup] running avoid on {ROBOTS} robots' in output, output[-3000:]
    assert '[bringup] error' not in output and 'was killed' not in output, output[-3000:]
    assert sorted(ROW.findall(output)) == sorted(f'epuck{i}' for i in range(ROBOTS)), output[-3000:]
    assert processes_in_this_domain() == []


def test_only_a_new_high_of_the_graph_is_progress():
    """A graph that loses a participant (its lease ran out on a loaded machine) and finds it again goes down and
    up: that is no progress, and counting it as such kept a stuck start-up waiting for ever (seen at 500 robots:
    4,509 topics, then 1,135, 1,932, 2,415, 1,505 for minutes)."""
    best = new_high(None, (4509, 479, 261, 0))
    assert best == (4509, 479, 261, 0)
    for dropped in [(1135, 478, 261, 0), (1932, 501, 261, 0), (2415, 501, 261, 0), (1505, 501, 261, 0)]:
        high = new_high(best, dropped)
        if high is not None:
            best = high
    assert best == (4509, 501, 261, 0)   # the node count grew once, then nothing
    assert new_high(best, (1505, 501, 261, 0)) is None and new_high(best, (4509, 501, 261, 0)) is None
    assert new_high(best, (100, 0, 262, 0)) == (4509, 501, 262, 0)   # one more controller found is progress


def test_a_simulators_robots_are_read_from_ir_raw_without_looking_at_the_graph(rclpy_context):
    """`--robots all` names a simulator's robots, and it always publishes `ir_raw`. Each node looked at the whole
    graph 10 times a second for a `proximity`-only driver until its `ir_raw` publisher showed up: with 500 robots
    that was all the process did, its DDS discovery starved, robots fell back to `proximity` and the simulator waited
    for their answers. A robot named on the command line may be a real one's: its node still looks."""
    from epuck_ros.behaviours import BEHAVIOURS
    from epuck_ros.nodes.behaviour_nodes import BehaviourNode

    simulated = BehaviourNode('avoid', BEHAVIOURS['avoid'], '/epuck0', ir_raw_only=True)
    named = BehaviourNode('avoid', BEHAVIOURS['avoid'], '/epuck1')

    def graph_looks(node: BehaviourNode) -> list[object]:
        return [timer for timer in node.timers if getattr(timer.callback, '__name__', '') == '_choose_ir_topic']

    try:
        assert graph_looks(simulated) == [] and len(graph_looks(named)) == 1
    finally:
        simulated.destroy_node()
        named.destroy_node()
