"""`evolve -o OUT`: evolve the obstacle-avoidance network; the fitness curve, the best genome and a controller.

Each generation's population is split into one batch per worker and scored on the sweep engine's Dask client
(`experiments.cluster.open_client`); a batch's scores do not depend on the split (see `evaluate`), and every random
draw of the algorithm comes from one generator seeded with --seed, so a seed gives the same files to the bit.
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

import numpy as np

from epuck_ros.evolution.controller import controller_script
from epuck_ros.evolution.evaluate import evaluate
from epuck_ros.evolution.ga import initial_population, next_generation
from epuck_ros.evolution.network import GENES
from epuck_ros.exit_codes import EXIT_FAILED, ignore_ctrl_c_at_exit, refuse
from epuck_ros.experiments.cluster import (
    ClusterError, add_cluster_arguments, check_cluster_arguments, default_workers, open_client)
from epuck_ros.experiments.interruption import exit_code, interrupts_ignored, terminate_as_interrupt
from epuck_ros.experiments.output import OutputError, OutputFolder

PAPER_POPULATION, PAPER_GENERATIONS = 80, 100
"""Floreano and Mondada (1994)."""
LIMITS = {'population': (2, 10000), 'generations': (1, 100000), 'seed': (0, 2 ** 32 - 1)}


def parse_args(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog='evolve', description='Evolve the obstacle-avoidance controller of Floreano and Mondada (1994): a '
        'single-layer recurrent network (8 IR inputs and a bias to 2 motors), fitness V (1 - sqrt(dv)) (1 - i), '
        'evaluated headless on the pure core (epuck_ros/Avoid-v0), each generation in parallel on Dask. Writes '
        'OUT/fitness.csv (generation, best, mean), OUT/fitness.png, OUT/best_genome.json and '
        'OUT/evolved_controller.py (a Webots controller: bringup --controller OUT/evolved_controller.py).',
        epilog='example: evolve -o evolve_out --population 80 --generations 100 --seed 1')
    parser.add_argument('-o', '--output', type=Path, required=True, help='output folder (made if missing)')
    parser.add_argument('--population', type=int, default=PAPER_POPULATION,
                        help=f'genomes per generation (2..10000; default {PAPER_POPULATION}, as the paper)')
    parser.add_argument('--generations', type=int, default=PAPER_GENERATIONS,
                        help=f'generations (1..100000; default {PAPER_GENERATIONS}, as the paper)')
    parser.add_argument('--duration', type=float, default=20.0,
                        help='simulated seconds each genome drives (0.032..3600; default 20)')
    parser.add_argument('--seed', type=int, default=0, help='seed of the whole evolution (0..2**32-1; default 0)')
    add_cluster_arguments(parser, 'every evaluation')
    args = parser.parse_args(argv)
    for name, (low, high) in LIMITS.items():
        if not low <= getattr(args, name) <= high:
            parser.error(f'--{name} must be from {low} to {high}, got {getattr(args, name)}')
    if not 0.032 <= args.duration <= 3600.0:
        parser.error(f'--duration must be from 0.032 to 3600 simulated seconds, got {args.duration}')
    check_cluster_arguments(parser, args)
    return args


def main(argv: list[str] | None = None) -> None:
    ignore_ctrl_c_at_exit()
    args = parse_args(sys.argv[1:] if argv is None else argv)
    folder = OutputFolder(args.output)
    began = time.monotonic()
    history: list[tuple[int, float, float]] = []
    best: dict = {'fitness': -np.inf}
    interrupted: KeyboardInterrupt | None = None
    try:
        with terminate_as_interrupt():
            folder.lock()   # if it exists: nothing is written before the cluster answers
            workers = min(default_workers() if args.workers is None else args.workers, args.population)
            with open_client(workers, args.scheduler) as client:
                folder.make()
                with EvolutionFiles(folder, args) as files:
                    evolve(args, client, history, best, files.generation)
    except (ClusterError, OutputError) as error:
        refuse(f'evolve: {error}')
    except Exception as error:  # noqa: BLE001 - Dask's KilledWorker (not imported without a cluster); else raised
        if type(error).__name__ != 'KilledWorker':
            raise
        print(f'evolve: the Dask workers died under a batch of generation {len(history)}, each time Dask tried '
              f'it (KilledWorker); {len(history)} generations written to {args.output}', file=sys.stderr)
        raise SystemExit(EXIT_FAILED) from None
    except KeyboardInterrupt as interruption:   # Ctrl-C or SIGTERM: what ran is written already
        interrupted = interruption
    try:
        with interrupts_ignored():
            if history:
                files.write_best(best, len(history))
                folder.replace('fitness.png', lambda out: draw_fitness(history, out))
    except OutputError as error:   # the disk filled up, say
        print(f'evolve: {error}', file=sys.stderr)
        raise SystemExit(EXIT_FAILED) from None
    ran = f'{len(history)} of {args.generations} generations' if interrupted else f'{len(history)} generations'
    if history:
        print(f'{"[evolve] interrupted: " if interrupted else "[evolve] "}{ran} of {args.population} in '
              f'{time.monotonic() - began:.1f} s; best fitness {best["fitness"]:.4f} (generation '
              f'{best["generation"]}); wrote {args.output}/fitness.csv, fitness.png, best_genome.json, '
              'evolved_controller.py', file=sys.stderr)
    else:
        print('[evolve] interrupted before the first generation ended', file=sys.stderr)
    if interrupted:
        raise SystemExit(exit_code(interrupted))


class EvolutionFiles:
    """The files of the generations so far, written as each generation ends (an interrupted or killed evolution
    keeps them): a row of OUT/fitness.csv per generation, and OUT/best_genome.json and OUT/evolved_controller.py
    written anew (whole, `OutputFolder.replace`) when the best genome changes and at the end, saying how many
    generations ran."""

    def __init__(self, folder: OutputFolder, args: argparse.Namespace) -> None:
        self.folder, self.args = folder, args
        self._fitness = open(folder.replace('fitness.csv', lambda out: None), 'a', newline='')
        self._rows = csv.writer(self._fitness)
        self._rows.writerow(['generation', 'best', 'mean'])

    def __enter__(self) -> EvolutionFiles:
        return self

    def __exit__(self, *exc: object) -> None:
        self._fitness.close()

    def generation(self, history: list[tuple[int, float, float]], best: dict, improved: bool) -> None:
        generation, top, mean = history[-1]
        self._rows.writerow([generation, repr(top), repr(mean)])
        self._fitness.flush()
        if improved:
            self.write_best(best, len(history))

    def write_best(self, best: dict, generations: int) -> None:
        """The best genome and its controller, after `generations` generations."""
        args = self.args
        settings = {'population': args.population, 'generations': generations, 'duration': args.duration,
                    'seed': args.seed}
        if generations < args.generations:
            settings['generations_asked'] = args.generations
        text = json.dumps({**best, **settings}, indent=1) + '\n'
        self.folder.replace('best_genome.json', lambda out: out.write(text.encode()))
        script = controller_script(best['genome'], best['generation'], best['fitness'], self.args.seed)
        self.folder.replace('evolved_controller.py', lambda out: out.write(script.encode()))


def evolve(args: argparse.Namespace, client: object | None, history: list[tuple[int, float, float]],
           best: dict, done: Callable[[list, dict, bool], None]) -> None:
    """Run the generations, appending (generation, best, mean) to `history` and keeping the best genome found in
    `best` (its fitness, generation and weights); `done(history, best, improved)` after each generation."""
    rng = np.random.default_rng(args.seed)
    population = initial_population(rng, args.population, GENES)
    batches = 1 if client is None else max(1, len(client.scheduler_info()['workers']))
    for generation in range(args.generations):
        trial_seed = int(rng.integers(2 ** 31))
        fitness = score(client, population, trial_seed, args.duration, batches)
        top = int(np.argmax(fitness))
        history.append((generation, float(fitness[top]), float(fitness.mean())))
        improved = bool(fitness[top] > best['fitness'])
        if improved:
            best.update(fitness=float(fitness[top]), generation=generation, genome=population[top].tolist())
        done(history, best, improved)
        print(f'[evolve] generation {generation}: best {fitness[top]:.4f} mean {fitness.mean():.4f}',
              file=sys.stderr, flush=True)
        if generation + 1 < args.generations:
            population = next_generation(rng, population, fitness)


def score(client: object | None, population: np.ndarray, seed: int, duration: float, batches: int) -> np.ndarray:
    """The population's fitness, in batches on the Dask workers (or here without a client)."""
    if client is None:
        return evaluate(population, seed, duration)
    parts = np.array_split(population, min(batches, len(population)))
    futures = client.map(evaluate, parts, [seed] * len(parts), [duration] * len(parts), pure=False)
    return np.concatenate(client.gather(futures))


def draw_fitness(history: list[tuple[int, float, float]], out: BinaryIO) -> None:
    """Best and mean fitness per generation, as the paper plots them."""
    import matplotlib
    matplotlib.use('Agg')
    from matplotlib.figure import Figure
    figure = Figure(figsize=(6, 3.6), dpi=100)
    axes = figure.add_subplot()
    generations = [row[0] for row in history]
    axes.plot(generations, [row[1] for row in history], label='best')
    axes.plot(generations, [row[2] for row in history], label='mean')
    axes.set_xlabel('generation')
    axes.set_ylabel('fitness  V (1 - sqrt(dv)) (1 - i)')
    axes.set_ylim(0.0, 1.0)
    axes.grid(alpha=0.3)
    axes.legend()
    figure.tight_layout()
    figure.savefig(out, format='png', metadata={'Software': None})


if __name__ == '__main__':
    main()
