"""`evolve` interrupted (issue 28, item 17): it writes as it goes, so Ctrl-C, SIGTERM and even SIGKILL keep the
generations that ran; Ctrl-C and SIGTERM exit 130 and 143 and say how many generations ran."""
from __future__ import annotations

import json
import signal
import subprocess
import time

import pytest
from conftest import BIN_DIR

from epuck_ros.evolution import cli

ASKED = 100_000
SETTINGS = ['--workers', '0', '--population', '4', '--duration', '0.5', '--seed', '2']


@pytest.mark.parametrize('number, code', [(signal.SIGINT, 130), (signal.SIGTERM, 143), (signal.SIGKILL, -9)])
def test_an_interrupted_evolution_keeps_the_generations_that_ran(tmp_path, number, code):
    """SIGTERM left an empty fitness.csv after 105 of 500 generations (exit 143, nothing written); Ctrl-C exited 0
    with a best_genome.json saying 500 generations after 106. Now each generation's row is written as it ends, the
    best genome whenever it changes: the files equal those of an evolution of as many generations, uninterrupted."""
    out = tmp_path / 'out'
    process = subprocess.Popen([str(BIN_DIR / 'evolve'), '-o', str(out), '--generations', str(ASKED), *SETTINGS],
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    fitness = out / 'fitness.csv'
    deadline = time.monotonic() + 120
    while not (fitness.exists() and len(fitness.read_text().splitlines()) >= 3):   # two generations written
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < deadline, 'no generation was written while evolve ran'
        time.sleep(0.02)
    process.send_signal(number)
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == code, stderr
    ran = len(fitness.read_text().splitlines()) - 1
    best = json.loads((out / 'best_genome.json').read_text())
    if number != signal.SIGKILL:
        assert f'[evolve] interrupted: {ran} of {ASKED} generations' in stderr and 'Traceback' not in stderr
        assert (best['generations'], best['generations_asked']) == (ran, ASKED)
        assert (out / 'fitness.png').stat().st_size > 1000
    cli.main(['-o', str(tmp_path / 'whole'), '--generations', str(ran), *SETTINGS])
    assert fitness.read_bytes() == (tmp_path / 'whole' / 'fitness.csv').read_bytes()
    if number == signal.SIGKILL:   # killed between a generation's row and its best genome, maybe: whole files
        assert best['generation'] <= ran and (out / 'evolved_controller.py').exists()
        return
    whole = json.loads((tmp_path / 'whole' / 'best_genome.json').read_text())
    assert {key: value for key, value in best.items() if not key.startswith('generations')} == \
        {key: value for key, value in whole.items() if not key.startswith('generations')}
    assert (out / 'evolved_controller.py').read_text() == (tmp_path / 'whole' / 'evolved_controller.py').read_text()


def test_a_batch_whose_dask_workers_died_is_one_line_and_the_generations_written(tmp_path, monkeypatch, capsys):
    """Dask gives up on a task whose workers died under it (KilledWorker): a traceback, before; now one line, exit
    1, and the generations that ran written."""
    from distributed import KilledWorker
    score = cli.score

    def dies_in_generation_2(client, population, seed, duration, batches):
        if dies_in_generation_2.calls == 2:
            raise KilledWorker('evaluate-1', None, 3)
        dies_in_generation_2.calls += 1
        return score(client, population, seed, duration, batches)
    dies_in_generation_2.calls = 0
    monkeypatch.setattr(cli, 'score', dies_in_generation_2)
    with pytest.raises(SystemExit) as ended:
        cli.main(['-o', str(tmp_path / 'out'), '--generations', '5', *SETTINGS])
    err = capsys.readouterr().err
    assert ended.value.code == 1 and 'Traceback' not in err
    assert 'the Dask workers died under a batch of generation 2' in err and '2 generations written' in err
    assert len((tmp_path / 'out' / 'fitness.csv').read_text().splitlines()) == 3


def test_evolve_and_sweep_in_this_process_leave_its_signal_handlers_as_they_were(tmp_path):
    """They ignore Ctrl-C and SIGTERM while they write their last files; they left them ignored for good, so a
    process started later from the same caller (a test's `evolve`) ignored Ctrl-C as well."""
    from epuck_ros.experiments import cli as sweep_cli
    before = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    cli.main(['-o', str(tmp_path / 'evolve'), '--generations', '1', *SETTINGS])
    spec = tmp_path / 'spec.yaml'
    spec.write_text('controllers: [avoid]\nseeds: [0]\nduration: 1\n')
    sweep_cli.main([str(spec), '-o', str(tmp_path / 'sweep'), '--workers', '0'])
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == before
