"""`evolve`: the same seed gives the same files to the bit, in this process or on Dask; its controller runs in ROS."""
from __future__ import annotations

import csv
import json
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
from conftest import BIN_DIR, processes_in_this_domain

from epuck_ros.envs.worlds import activations
from epuck_ros.evolution import cli
from epuck_ros.evolution.controller import controller_script
from epuck_ros.evolution.network import GENES, outputs
from epuck_ros.model import RobotModel

TINY = ['--population', '6', '--generations', '3', '--duration', '1', '--seed', '5']


def run(tmp_path: Path, name: str, *extra: str) -> Path:
    out = tmp_path / name
    cli.main(['-o', str(out), *TINY, *extra])
    return out


@pytest.fixture(scope='module')
def tiny_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One tiny evolution in this process, shared by the tests that read its files."""
    return run(tmp_path_factory.mktemp('evolve'), 'a', '--workers', '0')


def test_a_tiny_evolution_run_twice_gives_identical_files(tiny_run, tmp_path):
    first, second = tiny_run, run(tmp_path, 'b', '--workers', '0')
    names = ['fitness.csv', 'fitness.png', 'best_genome.json', 'evolved_controller.py']
    for name in names:
        assert (first / name).read_bytes() == (second / name).read_bytes(), name
    rows = list(csv.DictReader(open(first / 'fitness.csv')))
    assert [row['generation'] for row in rows] == ['0', '1', '2']
    assert all(-1.0 <= float(row['mean']) <= float(row['best']) <= 1.0 for row in rows)
    best = json.loads((first / 'best_genome.json').read_text())
    assert len(best['genome']) == GENES and best['fitness'] == max(float(row['best']) for row in rows)
    on_dask = tmp_path / 'c'   # the executable, its population split over a local Dask cluster of two workers
    result = subprocess.run([str(BIN_DIR / 'evolve'), '-o', str(on_dask), *TINY, '--workers', '2'],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    assert (on_dask / 'fitness.csv').read_bytes() == (first / 'fitness.csv').read_bytes()
    assert processes_in_this_domain() == []


@pytest.mark.parametrize('arguments, problem', [
    (['--population', '1'], '--population must be from 2 to 10000'),
    (['--generations', '0'], '--generations must be from 1 to 100000'),
    (['--duration', 'nan'], '--duration must be from 0.032 to 3600'),
    (['--workers', '-1'], '--workers must be 0 or more'),
])
def test_bad_options_are_one_line_and_exit_2(arguments, problem, tmp_path, capsys):
    with pytest.raises(SystemExit) as ended:
        cli.main(['-o', str(tmp_path), *arguments])
    assert ended.value.code == 2 and problem in capsys.readouterr().err


def test_an_output_folder_that_cannot_be_written_is_one_line_and_exit_2(tmp_path, capsys):
    blocker = tmp_path / 'file'
    blocker.write_text('')
    with pytest.raises(SystemExit) as ended:
        cli.main(['-o', str(blocker / 'out'), *TINY])
    assert ended.value.code == 2 and f'-o {blocker / "out"}: {blocker} is not a folder' in capsys.readouterr().err


def test_the_controller_script_computes_the_network_and_the_activations_of_the_evolution():
    """The script's activation of a raw value is the environment's to the bit (over and beyond the table's ends),
    and its network the evolution's."""
    genome = np.random.default_rng(1).uniform(-1, 1, GENES)
    source = controller_script(genome, 0, 0.5, 0)
    scope: dict = {}
    exec(source[:source.index('from controller import Robot')], scope)   # the imports
    exec(source[source.index('GENOME ='):source.index('robot = Robot()')], scope)   # the constants
    exec(source[source.index('def activation'):source.index('speeds = [0.0, 0.0]')], scope)
    model = RobotModel()
    raws = np.concatenate([[0.0, 30.0, 60.0, 67.19, 70.0, 120.0, 383.84, 1000.0, 2133.33, 4095.0, 5000.0],
                           np.random.default_rng(3).uniform(0.0, 4200.0, 200)])
    assert [scope['activation'](raw) for raw in raws.tolist()] == activations(raws, model).tolist()
    reach = 0.06 + (67.19 * (1 + 3 * 0.04897) - 104.09) / (67.19 - 104.09) * 0.01   # raw 77.1: nothing seen
    assert activations(np.array([77.0, 383.84, 1465.73, 4095.0]), model) == pytest.approx(
        [0.0, 1 - 0.02 / reach, 1 - 0.01 / reach, 1.0])
    activation, previous = np.random.default_rng(2).uniform(0, 1, 8), np.array([0.3, -0.2])
    expected = outputs(genome[None], activation[None], previous[None])[0]
    assert scope['network'](activation.tolist(), previous.tolist()) == pytest.approx(expected, abs=1e-12)


def test_the_evolved_controller_runs_unchanged_through_webots_controller_headless(tiny_run):
    """The file `evolve` wrote, as it is: exit 0 and the run's summary (simulated time, distance, contacts)."""
    script = tiny_run / 'evolved_controller.py'
    result = subprocess.run([str(BIN_DIR / 'webots_controller'), str(script), '--headless', '--duration', '3',
                             '--seed', '1'], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    simulated = re.search(r'^\[webots_controller\] simulated ([\d.]+) s in .* headless$', result.stdout, re.M)
    assert simulated and float(simulated[1]) == pytest.approx(3.0, abs=0.032), result.stdout
    summary = re.search(r'^\[webots_controller\] ([\d.]+) m in ([\d.]+) s, (\d+) contacts? with walls/obstacles; '
                        r'final pose .+$', result.stdout, re.M)
    assert summary and float(summary[1]) > 0.05, result.stdout   # evolved to drive: it went somewhere


def test_the_evolved_controller_runs_unchanged_through_bringup(launch, tmp_path):
    """A genome that ignores its sensors (bias 1 on both motors: tanh(1) of the top speed) drives straight."""
    genome = np.zeros(GENES)
    genome[8] = genome[8 + 11] = 1.0
    script = tmp_path / 'evolved_controller.py'
    script.write_text(controller_script(genome, 0, 0.0, 0))
    run = launch('bringup', '--controller', str(script), '--duration', '3', '--real-time-factor', '0')
    assert run.proc.wait(timeout=90) == 0, run.output()
    output = run.output()
    simulated = float(re.search(r'\[bringup\] simulated ([\d.]+) s', output)[1])
    distance = float(re.search(r'\[bringup\] (?:\w+: )?([\d.]+) m in', output)[1])
    speed = np.tanh(1.0) * 6.28 * 0.02
    assert distance == pytest.approx(speed * (simulated - 0.064), abs=5e-3), output
    assert processes_in_this_domain() == []


# --- the evolved controller the README shows (issue 26): it avoids ------------------------------------------------

EVOLVED = Path(__file__).resolve().parents[1] / 'epuck_ros' / 'webots' / 'examples' / 'evolved_avoid.py'
CORRIDOR = Path(__file__).resolve().parents[1] / 'epuck_ros' / 'worlds' / 'corridor.yaml'
AVOIDS = {'default': ([], 9.0), 'corridor': (['--world', str(CORRIDOR)], 8.0)}
"""World: its options, and the least distance (m) the controller drives in 120 s there."""
MOST_CONTACTS = 2


def summary(output: str) -> tuple[float, int]:
    """Distance (m) and contacts with walls and obstacles from a run's summary line (bringup, webots_controller)."""
    found = re.search(r'\] ([\d.]+) m in [\d.]+ s, (\d+) contacts? with walls/obstacles', output)
    assert found, output
    return float(found[1]), int(found[2])


def test_the_shipped_evolved_controller_is_what_evolve_writes():
    """examples/evolved_avoid.py is `evolve -o OUT --seed 1`'s OUT/evolved_controller.py, byte for byte: the current
    template around the genome it holds."""
    source = EVOLVED.read_text()
    constants: dict = {}
    exec(source[source.index('GENOME ='):source.index('robot = Robot()')], constants)
    genome = constants['GENOME']
    generation, fitness, seed = re.search(r'generation (\d+), fitness ([\d.e-]+) \(seed (\d+)\)', source).groups()
    assert controller_script(genome, int(generation), float(fitness), int(seed)) == source


def headless(world: str, seed: int, duration: float) -> subprocess.Popen:
    """`webots_controller evolved_avoid.py --headless` in `world` (started, not waited for)."""
    return subprocess.Popen([str(BIN_DIR / 'webots_controller'), str(EVOLVED), '--headless', *AVOIDS[world][0],
                             '--duration', str(duration), '--seed', str(seed)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def finished(run: subprocess.Popen) -> str:
    out, err = run.communicate(timeout=300)
    assert run.returncode == 0, err
    return out


@pytest.mark.parametrize('world', sorted(AVOIDS))
def test_the_evolved_controller_avoids_for_120_s_from_several_seeds(world):
    """The README's figures: 120 simulated seconds (headless: the run bringup makes, without DDS), seeds 0 to 2."""
    least = AVOIDS[world][1]
    runs = [headless(world, seed, 120) for seed in (0, 1, 2)]   # at once: each mostly waits on its script
    for seed, run in enumerate(runs):
        output = finished(run)
        distance, contacts = summary(output)
        print(f'evolved_avoid.py in the {world} world, seed {seed}: {distance:.3f} m in 120 s, {contacts} contacts')
        assert contacts <= MOST_CONTACTS and distance >= least, (world, seed, output)


@pytest.mark.parametrize('world', sorted(AVOIDS))
def test_the_evolved_controller_avoids_over_ros_as_headless(launch, world):
    """The README's run through `bringup --controller` (lockstep, as fast as possible): 120 simulated seconds, at
    most two contacts, and the distance and contacts of the headless run of the same seed, to the bit."""
    reference = headless(world, 0, 120)
    run = launch('bringup', '--controller', str(EVOLVED), *AVOIDS[world][0], '--duration', '120',
                 '--real-time-factor', '0')
    assert run.proc.wait(timeout=300) == 0, run.output()
    distance, contacts = summary(run.output())
    print(f'evolved_avoid.py over ROS in the {world} world: {distance:.3f} m in 120 s, {contacts} contacts')
    assert (distance, contacts) == summary(finished(reference)), run.output()
    assert contacts <= MOST_CONTACTS and distance >= AVOIDS[world][1], run.output()
    assert processes_in_this_domain() == []
