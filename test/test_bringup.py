"""The entry script: starts sim + behaviour (+ recorder) as processes and always stops them all."""
from __future__ import annotations

import os
import re
import signal

import pytest
from conftest import processes_in_this_domain

from epuck_ros.bag.reader import Bag as BagReader
from epuck_ros.bringup import parse_args


def behaviour_pids(name: str) -> list[int]:
    return [pid for pid, cmd in processes_in_this_domain() if re.search(rf'/{name}\b', cmd)]


def test_parameters_go_to_the_node_that_declares_them():
    args = parse_args(['rectangle', '--seed', '7', '--no-noise', '-p', 'turn_mode:=timed',
                       '-p', 'cmd_timeout:=2.0', '-p', 'rectangle.side_a:=0.2', '-p', 'sim.time_step:=0.016'])
    assert args.behaviour_params == ['turn_mode:=timed', 'side_a:=0.2']
    assert set(args.sim_params) >= {'seed:=7', 'noise:=false', 'cmd_timeout:=2.0', 'time_step:=0.016',
                                    'real_time_factor:=1.0'}


@pytest.mark.parametrize('argv, message', [
    (['dance'], 'invalid choice'),
    (['avoid', '--duration', '-3'], '--duration'),
    (['avoid', '-p', 'oops'], 'NAME:=VALUE'),
    (['avoid', '-p', 'turtle.speed:=1'], 'unknown node'),
    (['avoid', '--world', '/no/such.yaml'], 'no such file'),
])
def test_bad_arguments_are_refused(argv, message, capsys):
    with pytest.raises(SystemExit) as exit_info:
        parse_args(argv)
    assert exit_info.value.code == 2
    assert message in capsys.readouterr().err


def test_a_run_with_duration_ends_by_itself_and_leaves_no_process(launch):
    run = launch('bringup', 'forward', '--duration', '4', '--real-time-factor', '8', '--no-noise')
    assert run.proc.wait(timeout=60) == 0, run.output()
    summary = re.search(r'simulated ([\d.]+) s .* distance travelled ([\d.]+) m; collisions (\d+)', run.output())
    assert summary, run.output()
    simulated, distance, collisions = float(summary[1]), float(summary[2]), int(summary[3])
    assert simulated == pytest.approx(4.0, abs=0.032)
    # The simulator resumes once the behaviour is up: it drives at 0.0628 m/s for (almost) the whole run.
    assert 0.0628 * (simulated - 0.2) < distance <= 0.0628 * simulated + 1e-3
    assert collisions == 0
    assert processes_in_this_domain() == []


def test_sigterm_stops_every_child_cleanly(launch):
    run = launch('bringup', 'spin', '--real-time-factor', '4')
    run.wait_for_output('[bringup] running spin', timeout=30)
    run.proc.send_signal(signal.SIGTERM)
    assert run.proc.wait(timeout=40) == 0, run.output()
    assert processes_in_this_domain() == []


def test_a_dying_behaviour_stops_the_rest_and_fails_the_run(launch):
    run = launch('bringup', 'circle', '--real-time-factor', '4')
    run.wait_for_output('[bringup] running circle', timeout=30)
    (pid,) = behaviour_pids('circle')
    os.kill(pid, signal.SIGKILL)
    assert run.proc.wait(timeout=40) == 1
    assert 'circle exited unexpectedly with code -9' in run.output()
    assert processes_in_this_domain() == []


def test_avoid_for_five_simulated_minutes_without_a_collision(launch):
    """Noise on, default world, through real processes: the bound is the one of test_behaviours' pure runs
    (cruising at 0.0628 m/s at least half of 300 s gives > 9.4 m; spinning in place gives ~0)."""
    run = launch('bringup', 'avoid', '--duration', '300', '--real-time-factor', '10', '--seed', '5')
    assert run.proc.wait(timeout=240) == 0, run.output()
    summary = re.search(r'simulated ([\d.]+) s .* distance travelled ([\d.]+) m; collisions (\d+)', run.output())
    assert summary, run.output()
    assert float(summary[1]) == pytest.approx(300.0, abs=0.032)
    assert int(summary[3]) == 0
    assert float(summary[2]) > 9.4


def test_lockstep_runs_are_identical(launch, tmp_path):
    """Noise on, seed fixed: with --lockstep the recorded trajectories of two runs are the same to the last bit
    (the messages themselves; the recorder's log times depend on when each message arrived)."""
    trajectories, logs = [], []
    for run_index in range(2):
        bag = tmp_path / f'run{run_index}'
        run = launch('bringup', 'avoid', '--duration', '12', '--real-time-factor', '0', '--lockstep', '--seed', '3',
                     '--record', str(bag))
        assert run.proc.wait(timeout=120) == 0, run.output()
        logs.append('\n'.join(line for line in run.output().splitlines() if '[avoid]' in line or 'bringup]' in line or 'lockstep:' in line))
        with BagReader(bag) as reader:
            messages = [m.data for m in reader.messages(topics=['/ground_truth'])]
        # In lockstep the sim re-sends its first step until the behaviour answers: drop such repeats.
        trajectories.append([data for i, data in enumerate(messages) if i == 0 or data != messages[i - 1]])
    assert [len(t) for t in trajectories] == [round(12 / 0.032)] * 2, '\n----\n'.join(logs)
    differ = [i for i, (a, b) in enumerate(zip(*trajectories)) if a != b]
    assert not differ, f'{len(differ)} steps differ, the first at step {differ[0] + 1}:\n' + '\n----\n'.join(logs)
