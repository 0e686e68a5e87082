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

from epuck_ros.evolution import cli
from epuck_ros.evolution.controller import controller_script
from epuck_ros.evolution.network import GENES, outputs

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
    assert all(0.0 <= float(row['mean']) <= float(row['best']) <= 1.0 for row in rows)
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


def test_the_controller_script_computes_the_network_of_the_evolution():
    genome = np.random.default_rng(1).uniform(-1, 1, GENES)
    source = controller_script(genome, 0, 0.5, 0)
    network = source[source.index('def activation'):source.index('speeds = [0.0, 0.0]')]
    scope = {'math': __import__('math'), 'GENOME': genome.tolist(), 'FAR': 67.19, 'NEAR': 4095.0}
    exec(network, scope)
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
    summary = re.search(r'^\[webots_controller\] ([\d.]+) m in ([\d.]+) s, (\d+) contacts? with walls/obstacles$',
                        result.stdout, re.M)
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
