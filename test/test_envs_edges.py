"""The environments at their edges (issue 28, items 7 and 20).

Actions beyond [-1, 1] are clipped (whatever their size), numbers no float holds refused; step() before reset() and
after the swarm's episode are refused; an unknown agent is refused; render() without a render mode warns; infos say
what they hold; a seed beyond `bringup --seed`'s is refused everywhere; a script's deep recursion is reported as
Python reports it.
"""
from __future__ import annotations

import re
import subprocess
import sys
import threading
import warnings
from pathlib import Path

import gymnasium
import numpy as np
import pytest

import epuck_ros.envs  # noqa: F401  (registers epuck_ros/Avoid-v0)
from epuck_ros.envs import swarm_avoid_v0
from epuck_ros.experiments.spec import SpecError, load_spec
from epuck_ros.nodes.sim_node import SIM_PARAMETERS
from epuck_ros import simulation
from epuck_ros.simulation import CommandError
from epuck_ros.webots import runner

AVOID = 'epuck_ros.envs:epuck_ros/Avoid-v0'


def first_steps(env, action, steps: int = 5) -> list[np.ndarray]:
    env.reset(seed=4)
    return [env.step(action)[0] for _ in range(steps)]


@pytest.mark.parametrize('action, same_as', [([1e308, 0.0], [1.0, 0.0]), ([5.0, -5.0], [1.0, -1.0]),
                                             ([-1e300, 2], [-1.0, 1.0])])
def test_an_action_beyond_the_box_is_clipped_whatever_its_size(action, same_as):
    """[1e308, 0] was refused as 'left=inf' (1e308 x 6.28 overflowed) while [5, -5] was clamped."""
    env = gymnasium.make(AVOID, noise=False)
    assert all(np.array_equal(a, b) for a, b in zip(first_steps(env, action), first_steps(env, same_as)))
    vector = gymnasium.make_vec(AVOID, num_envs=2, vectorization_mode='vector_entry_point', noise=False)
    vector.reset(seed=4)
    observation = vector.step(np.array([action, same_as]))[0]
    assert observation[:, 8:].tolist() == [same_as, same_as]   # the wheel speeds applied


@pytest.mark.parametrize('action', [[10 ** 400, 0], [0, -10 ** 400]])
def test_a_number_no_float_holds_is_a_command_error(action):
    env = gymnasium.make(AVOID)
    env.reset(seed=0)
    with pytest.raises(CommandError, match='too large for a float'):
        env.step(action)
    vector = gymnasium.make_vec(AVOID, num_envs=2, vectorization_mode='vector_entry_point')
    vector.reset(seed=0)
    with pytest.raises(CommandError, match='too large for a float'):
        vector.step([[0, 0], action])
    swarm = swarm_avoid_v0.parallel_env(robots=1)
    swarm.reset(seed=0)
    with pytest.raises(CommandError, match='too large for a float'):
        swarm.step({'epuck0': action})


def test_step_before_reset_is_reset_needed_not_an_attribute_error():
    with pytest.raises(gymnasium.error.ResetNeeded, match=r'reset\(\) before step\(\)'):
        gymnasium.make(AVOID).unwrapped.step(np.zeros(2))
    with pytest.raises(RuntimeError, match=r'reset\(\) before step\(\)'):
        swarm_avoid_v0.parallel_env(robots=2).step({'epuck0': np.zeros(2), 'epuck1': np.zeros(2)})


def test_the_swarm_refuses_an_unknown_agent_and_a_step_after_the_end():
    env = swarm_avoid_v0.parallel_env(robots=2, duration=0.064)
    env.reset(seed=1)
    with pytest.raises(ValueError, match='no agent epuck7 in this episode'):
        env.step({'epuck0': np.zeros(2), 'epuck1': np.zeros(2), 'epuck7': np.zeros(2)})
    with pytest.raises(ValueError, match='expected a dict of actions'):
        env.step([np.zeros(2), np.zeros(2)])
    time = env.sim.time
    while env.agents:
        env.step({agent: np.ones(2) for agent in env.agents})
    ended = env.sim.time
    assert ended == pytest.approx(time + 0.064)
    with pytest.raises(RuntimeError, match='episode has ended'):
        env.step({})
    assert env.sim.time == ended, 'the world stood still'
    env.reset(seed=1)
    env.step({agent: np.zeros(2) for agent in env.agents})


def test_the_swarms_infos_say_each_agents_contacts_and_touching_to_the_end():
    """Final infos were empty: each agent's contacts (with robots among them) and whether it touches, every step."""
    env = swarm_avoid_v0.parallel_env(robots=3, duration=3.0, noise=False)
    env.reset(seed=2)
    touched = False
    while env.agents:
        _, _, _, truncations, infos = env.step({agent: np.array([1.0, 0.9]) for agent in env.agents})
        assert set(infos) == set(truncations)
        sim = env.sim
        for index, agent in enumerate(env.possible_agents):
            assert infos[agent] == {'contacts': int(sim.collisions[index]),
                                    'robot_contacts': int(sim.robot_collisions[index]),
                                    'touching': bool(sim.in_contact[index])}
            touched |= infos[agent]['touching']
    assert all(truncations.values()) and infos['epuck0'] and touched, 'the final infos hold the figures'


def test_the_swarm_renders_as_avoid_v0_does():
    env = swarm_avoid_v0.parallel_env(robots=3, render_mode='rgb_array')
    with pytest.raises(gymnasium.error.ResetNeeded, match=r'reset\(\) before render\(\)'):
        env.render()
    env.reset(seed=1)
    first = env.render()
    for _ in range(20):
        env.step({agent: np.ones(2) for agent in env.agents})
    frame = env.render()
    assert frame.shape == (400, 400, 3) and frame.dtype == np.uint8 and not np.array_equal(first, frame)
    aec = swarm_avoid_v0.env(robots=3, render_mode='rgb_array')
    aec.reset(seed=1)
    assert aec.render().shape == (400, 400, 3)


@pytest.mark.parametrize('make', [
    lambda: gymnasium.make(AVOID).unwrapped,
    lambda: gymnasium.make_vec(AVOID, num_envs=2, vectorization_mode='vector_entry_point'),
    lambda: swarm_avoid_v0.parallel_env(robots=2),
    lambda: swarm_avoid_v0.env(robots=2),
])
def test_render_without_a_render_mode_says_so(make):
    env = make()
    env.reset(seed=0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter('always')
        assert env.render() is None
    assert any("render_mode='rgb_array'" in str(w.message) for w in caught), [str(w.message) for w in caught]


def test_one_seed_bound_for_the_sim_a_spec_and_headless(tmp_path):
    """`seeds: {first: 2**63 - 1, count: 2}` gave the trial seed 2**63, which `--headless` refused; and seeds beyond
    2**31 - 1 ran in a sweep though `bringup --seed` refuses them: one bound, the simulator's."""
    MAX_SEED = simulation.MAX_SEED
    assert [spec.range for spec in SIM_PARAMETERS if spec.name == 'seed'] == [(0, MAX_SEED)]
    spec = tmp_path / 'spec.yaml'
    for seeds, refusal in ((f'{{first: {MAX_SEED}, count: 2}}', f'seeds: the last seed, {MAX_SEED + 1}, is above'),
                           ('{first: 9223372036854775807, count: 2}', 'seeds.first: expected a whole number'),
                           (f'[0, {MAX_SEED + 1}]', r'seeds\[1\]: expected a whole number')):
        spec.write_text(f'controllers: [avoid]\nworlds: [default]\nrobots: [1]\nseeds: {seeds}\nduration: 1\n'
                        'noise: true\n')
        with pytest.raises(SpecError, match=refusal):
            load_spec(spec)
    spec.write_text(f'controllers: [avoid]\nworlds: [default]\nrobots: [1]\nseeds: {{first: {MAX_SEED}, count: 1}}\n'
                    'duration: 1\nnoise: true\n')
    assert [trial.seed for trial in load_spec(spec).trials] == [MAX_SEED]
    script = Path(runner.EXAMPLES_DIR) / 'spin.py'
    run = subprocess.run([sys.executable, '-m', 'epuck_ros.webots_controller', str(script), '--headless', '--seed',
                          str(MAX_SEED + 1), '--duration', '0.1'], capture_output=True, text=True)
    assert run.returncode == 2 and f'--seed must be from 0 to {MAX_SEED}' in run.stderr


def test_a_script_recursing_deep_is_reported_as_python_reports_it(tmp_path, capfd):
    """A script that recursed 10**6 frames deep took minutes to report (Python's traceback module located every
    frame's columns); the report keeps the innermost TRACEBACK_LIMIT frames, as Python's own does."""
    script = tmp_path / 'deep.py'
    script.write_text('import sys\nsys.setrecursionlimit(30000)\n\n\ndef down(n):\n    return down(n + 1)\n\n\n'
                      'down(0)\n')
    outcome = []
    threading.stack_size(256 << 20)
    try:
        thread = threading.Thread(target=lambda: outcome.append(runner.run_script(script, [])))
        thread.start()
        thread.join()
    finally:
        threading.stack_size(0)
    code, line = outcome[0]
    assert code == 1 and line == 'RecursionError: maximum recursion depth exceeded (line 6 of deep.py)'
    report = capfd.readouterr().err
    repeated = [int(n) for n in re.findall(r'Previous line repeated (\d+) more times', report)]
    assert repeated and max(repeated) < runner.TRACEBACK_LIMIT, repeated
    assert report.count(f'File "{script}"') <= 4 and 'runner.py' not in report
