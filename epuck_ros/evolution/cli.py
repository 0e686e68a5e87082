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
from pathlib import Path

import numpy as np

from epuck_ros.evolution.controller import controller_script
from epuck_ros.evolution.evaluate import evaluate
from epuck_ros.evolution.ga import initial_population, next_generation
from epuck_ros.evolution.network import GENES
from epuck_ros.experiments.cluster import (
    ClusterError, add_cluster_arguments, check_cluster_arguments, open_client)

EXIT_BAD_INPUT, EXIT_INTERRUPTED = 2, 130
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
    args = parse_args(sys.argv[1:] if argv is None else argv)
    try:
        args.output.mkdir(parents=True, exist_ok=True)
        (args.output / 'fitness.csv').touch()
    except OSError as error:
        print(f'evolve: -o {args.output}: cannot write there: {error.strerror}', file=sys.stderr)
        raise SystemExit(EXIT_BAD_INPUT) from None
    began = time.monotonic()
    history: list[tuple[int, float, float]] = []
    best: dict = {'fitness': -np.inf}
    try:
        with open_client(args.workers, args.scheduler) as client:
            evolve(args, client, history, best)
    except ClusterError as error:
        print(f'evolve: {error}', file=sys.stderr)
        raise SystemExit(EXIT_BAD_INPUT) from None
    except KeyboardInterrupt:
        print(f'[evolve] interrupted after {len(history)} generations', file=sys.stderr)
        if not history:
            raise SystemExit(EXIT_INTERRUPTED) from None
    write_outputs(args, history, best)
    print(f'[evolve] {len(history)} generations of {args.population} in {time.monotonic() - began:.1f} s; '
          f'best fitness {best["fitness"]:.4f} (generation {best["generation"]}); wrote {args.output}/fitness.csv, '
          'fitness.png, best_genome.json, evolved_controller.py', file=sys.stderr)


def evolve(args: argparse.Namespace, client: object | None, history: list[tuple[int, float, float]],
           best: dict) -> None:
    """Run the generations, appending (generation, best, mean) to `history` and keeping the best genome found in
    `best` (its fitness, generation and weights), so an interruption leaves what was done."""
    rng = np.random.default_rng(args.seed)
    population = initial_population(rng, args.population, GENES)
    batches = 1 if client is None else max(1, len(client.scheduler_info()['workers']))
    for generation in range(args.generations):
        trial_seed = int(rng.integers(2 ** 31))
        fitness = score(client, population, trial_seed, args.duration, batches)
        top = int(np.argmax(fitness))
        history.append((generation, float(fitness[top]), float(fitness.mean())))
        if fitness[top] > best['fitness']:
            best.update(fitness=float(fitness[top]), generation=generation, genome=population[top].tolist())
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


def write_outputs(args: argparse.Namespace, history: list[tuple[int, float, float]], best: dict) -> None:
    with open(args.output / 'fitness.csv', 'w', newline='') as out:
        writer = csv.writer(out)
        writer.writerow(['generation', 'best', 'mean'])
        writer.writerows([generation, repr(top), repr(mean)] for generation, top, mean in history)
    settings = {name: getattr(args, name) for name in ('population', 'generations', 'duration', 'seed')}
    (args.output / 'best_genome.json').write_text(json.dumps({**best, **settings}, indent=1) + '\n')
    (args.output / 'evolved_controller.py').write_text(
        controller_script(best['genome'], best['generation'], best['fitness'], args.seed))
    draw_fitness(history, args.output / 'fitness.png')


def draw_fitness(history: list[tuple[int, float, float]], path: Path) -> None:
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
    figure.savefig(path, metadata={'Software': None})


if __name__ == '__main__':
    main()
