"""`evolve -o OUT`: evolve the obstacle-avoidance network; the fitness curve, the best genome and a controller."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

EXIT_BAD_INPUT = 2


def parse_args(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog='evolve', description='Evolve the obstacle-avoidance controller of Floreano and Mondada (1994): a '
        'single-layer recurrent network (8 IR inputs and a bias to 2 motors), fitness V (1 - sqrt(dv)) (1 - i), '
        'evaluated headless on the pure core, each generation in parallel on Dask. Writes OUT/fitness.csv '
        '(generation, best, mean), OUT/fitness.png, OUT/best_genome.json and OUT/evolved_controller.py.',
        epilog='example: evolve -o evolve_out --population 80 --generations 100 --seed 1')
    parser.add_argument('-o', '--output', type=Path, required=True, help='output folder (made if missing)')
    parser.add_argument('--population', type=int, default=80, help='genomes per generation (2..10000; default 80)')
    parser.add_argument('--generations', type=int, default=100, help='generations (1..100000; default 100)')
    parser.add_argument('--seed', type=int, default=0, help='seed of the whole evolution (0..2**32-1; default 0)')
    parser.add_argument('--workers', type=int, default=None, help='local Dask worker processes (default: one '
                        'per core); 0 = every evaluation in this process')
    parser.add_argument('--scheduler', help='tcp://HOST:PORT of an existing Dask scheduler')
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> None:
    parse_args(sys.argv[1:] if argv is None else argv)
    print('evolve: not implemented yet', file=sys.stderr)
    raise SystemExit(1)


if __name__ == '__main__':
    main()
