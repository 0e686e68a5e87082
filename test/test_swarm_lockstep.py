"""A swarm through the swarm topics (issue 34): `bringup avoid --robots N` drives every robot from one `avoid`
process through one `swarm/observation` and one `swarm/command` per step, and the run is its headless trial's to
the bit (same seed, same run), recorded or followed by bringup's monitor from `swarm/observation`."""
from __future__ import annotations

from pathlib import Path

import pytest
from conftest import processes_in_this_domain

from same_run import Case, bringup_truth, difference, headless_truth

from epuck_ros.bag.reader import Bag
from epuck_ros.bag.summary_text import format_figures
from epuck_ros.experiments.trial import Trial, controller_from, run

ROBOTS = 30


def test_a_swarm_through_its_swarm_topics_is_its_headless_trial_to_the_bit(tmp_path):
    case = Case('avoid', robots=ROBOTS, seed=5, duration=2.0)
    expected = headless_truth(case)
    got, output = bringup_truth(case, tmp_path / 'bag')
    assert difference(expected, got) == '', output[-3000:]
    assert '[bringup] reproducible: every step was answered' in output, output[-3000:]
    with Bag(tmp_path / 'bag') as bag:
        topics = {topic.name: topic for topic in bag.topics.values()}
    # one answer per step for all the robots, none on the robots' own wheel_cmd topics
    assert topics['/swarm/command'].message_count >= expected.shape[0], sorted(topics)
    assert not [name for name in topics if name.endswith('/wheel_cmd')], sorted(topics)
    assert topics['/swarm/observation'].message_count >= expected.shape[0]
    assert processes_in_this_domain() == []


@pytest.mark.parametrize(('robots', 'recorded'), [(ROBOTS, False), (200, False), (200, True)])
def test_bringups_summary_of_a_swarm_is_the_headless_trials(launch, tmp_path, robots, recorded):
    """Unrecorded, bringup's monitor tallies every robot's ground truth from `swarm/observation` (not one
    `ground_truth` topic per robot): its lines are the headless tally's, printed by the same code; 200 robots in a
    10 m arena too (issue 34: the swarm's run equal to headless in the suite; 1,000 robots in
    benchmarks/bench_swarm_lockstep.py). Recorded, from 200 robots the bag holds no robot's own topics (nobody read
    them: the simulator never made them) and the summary is read from its swarm observation, the same lines."""
    world = 'default'
    if robots > 100:   # the built-in 1 m arena holds about a hundred e-pucks
        world = str(tmp_path / 'arena.yaml')
        Path(world).write_text('arena: {size: [10.0, 10.0]}\n')
    _, tally = run(Trial(controller_from('avoid'), world=world, robots=robots, seed=2, duration=1.0))
    run_ = launch('bringup', 'avoid', '--robots', str(robots), '--seed', '2', '--duration', '1',
                  '--real-time-factor', '0', *(['--world', world] if world != 'default' else []),
                  *(['--record', str(tmp_path / 'bag')] if recorded else []))
    assert run_.proc.wait(timeout=600) == 0, run_.output()[-3000:]
    output = run_.output()
    for line in format_figures(tally.figures).splitlines():
        assert f'[bringup] {line}\n' in output, (line, output[-3000:])
    assert '[bringup] reproducible: every step was answered' in output, output[-3000:]
    assert processes_in_this_domain() == []
    if recorded:
        with Bag(tmp_path / 'bag') as bag:
            assert not [name for name in bag.topics if name.startswith('/epuck')], sorted(bag.topics)
