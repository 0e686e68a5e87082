#!/usr/bin/env python3
"""Makes every picture of the manual (docs/images/*.png) with the package's own commands, and checks them.

    python scripts/make_pictures.py                   # remake them all in docs/images/
    python scripts/make_pictures.py --only sweep      # some of them (names below), or --out DIR elsewhere
    python scripts/make_pictures.py --check           # remake them in a scratch folder and compare (test_pictures)
    python scripts/make_pictures.py --evolve          # also rerun `evolve --seed 1` (80 x 100, minutes) for fitness

Each picture is the output of the commands the manual shows, run as they are (the senses' runs headless: the same
run and bag as `bringup --controller ... --record`, to the bit, without DDS). `fitness` is drawn from
docs/images/fitness.csv, the `fitness.csv` of `evolve -o OUT --seed 1` (80 x 100): the whole run takes minutes, so
--check reruns its first generations and compares them with the file's. `view` is a screenshot of the live view in
headless Chromium, taken by test/test_view_browser.py; it needs chromium and chromedriver, and is not compared (a
live page is not the same twice to the pixel).

--check also checks the manual's figures about the pictures (the light seeker's closest approach, the red-box
finder's stop, the learned policy's table, the evolution's fitness). A picture differs when its pixels do by more
than TOLERANCE (RMS, of 255): a stale picture is far beyond it, a remade one within it.
"""
from __future__ import annotations

import argparse
import csv
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
IMAGES = ROOT / 'docs' / 'images'
MANUAL = [ROOT / 'README.md', *sorted((ROOT / 'docs').glob('*.md'))]
"""The README and the manual's pages (docs/_incoming/, a staging area, is not the manual)."""
BIN = Path(sys.executable).parent
EXAMPLES = ROOT / 'epuck_ros' / 'webots' / 'examples'
WORLDS = ROOT / 'epuck_ros' / 'worlds'
FITNESS_CSV = IMAGES / 'fitness.csv'
"""The data of fitness.png: `evolve -o OUT --seed 1`'s fitness.csv (80 genomes x 100 generations)."""
CHECKED_GENERATIONS = 2
"""Generations --check reruns to see that fitness.csv is still what `evolve --seed 1` makes."""
TOLERANCE = 2.0
"""RMS difference (of 255) within which a remade picture is the committed one (anti-aliasing, a font's hinting)."""
CAMERA_VIEWS = [('coloured_objects.yaml', (-0.15, -0.1, 0.55), 'coloured objects: the red box ahead'),
                ('line_track.yaml', (-0.03, -0.25, 0.0), 'line track: the oval ahead'),
                ('lit_arena.yaml', (-0.2, -0.2, 0.6), 'lit arena: the yellow disc under the light')]
"""The camera picture: (world, robot pose, title) of each view."""
ARRIVED = 0.05
"""m from the light within which the manual counts the light seeker as there."""


@dataclass
class Picture:
    """How one picture is made (`make(out, work)` writes out/<name>.png; `work` is a scratch folder) and the manual's
    figures about it that --check verifies (`facts(work)`: texts the manual must contain)."""

    name: str
    make: Callable[[Path, Path], None]
    facts: Callable[[Path], list[str]] = field(default=lambda work: [])
    compared: bool = True


def run(*command: str | Path, cwd: Path = ROOT, **environment: str) -> str:
    """Run a command of the package; its output, or SystemExit with it if it failed."""
    done = subprocess.run([str(part) for part in command], cwd=cwd, capture_output=True, text=True,
                          env=dict(os.environ, MPLBACKEND='Agg', **environment))
    if done.returncode:
        raise SystemExit(f'[pictures] failed ({done.returncode}): {" ".join(map(str, command))}\n'
                         f'{done.stdout[-2000:]}{done.stderr[-2000:]}')
    return done.stdout + done.stderr


def bag_plot(bag: Path, png: Path) -> None:
    run(BIN / 'bag', 'plot', bag, '-o', png)


def headless(script: str, world: str, duration: float, bag: Path) -> None:
    """The run `bringup --controller SCRIPT --world WORLD --duration D --real-time-factor 0 --record BAG` makes."""
    shutil.rmtree(bag, ignore_errors=True)
    run(BIN / 'webots_controller', EXAMPLES / script, '--headless', '--world', WORLDS / world, '--duration',
        str(duration), '--record', bag)


def sample_bag(name: str) -> Callable[[Path, Path], None]:
    return lambda out, work: bag_plot(ROOT / 'bags' / name, out / f'bag_{name}.png')


def senses_run(script: str, world: str, duration: float) -> Callable[[Path, Path], None]:
    stem = script.removesuffix('.py')

    def make(out: Path, work: Path) -> None:
        headless(script, world, duration, work / stem)
        bag_plot(work / stem, out / f'senses_{stem}.png')
    return make


def light_seeker_facts(work: Path) -> list[str]:
    """Its contacts, when it reached the light (within ARRIVED) and how close it came (the manual says so)."""
    run_data, summary = track(work / 'light_seeker')
    light = run_data.world.appearance.lights[0]
    path = run_data.trajectory
    distance = [math.hypot(x - light.x, y - light.y) for x, y in zip(path.x.tolist(), path.y.tolist())]
    arrived = next(t for t, d in zip(path.t.tolist(), distance) if d < ARRIVED)
    contacts = 'no contact' if not summary.collisions else f'{summary.collisions} contact(s)'
    return [f'{contacts} on the way', f'reaches the light at about {arrived:.0f} simulated seconds',
            f'{min(distance):.3f} m at the closest']


def red_box_facts(work: Path) -> list[str]:
    """Where it stopped: its distance from the red box's centre."""
    run_data, _ = track(work / 'find_red_box')
    world = run_data.world
    box = next(box for index, box in enumerate(world.boxes) if world.appearance.box_color(index) == (0.9, 0.1, 0.1))
    x, y = float(run_data.trajectory.x[-1]), float(run_data.trajectory.y[-1])
    return [f'stops {math.hypot(box.x - x, box.y - y):.2f} m from the box\'s centre']


def track(bag: Path) -> tuple:
    """The one robot's run in a bag and its summary (the code of `bag summary`)."""
    from epuck_ros.bag.reader import Bag
    from epuck_ros.bag.run_summary import summarise
    from epuck_ros.bag.runs import load_runs
    with Bag(bag) as opened:
        run_data = load_runs(opened)[0]
    return run_data, summarise(run_data)


def camera_views(out: Path, work: Path) -> None:
    """What the e-puck's camera sees (52 x 39, drawn 8 times larger) in three shipped worlds, rendered by the pure
    core (epuck_ros.sensors.camera)."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from epuck_ros.simulation import Simulation
    from epuck_ros.world import load_world
    from epuck_ros.world.data import RobotStart
    figure, axes = plt.subplots(1, len(CAMERA_VIEWS), figsize=(15, 4.2))
    for axis, (name, pose, title) in zip(axes, CAMERA_VIEWS):
        sim = Simulation(load_world(WORLDS / name).with_robots([RobotStart('epuck', *pose)]), noise=False)
        sim.senses.want('camera', [0])
        axis.imshow(sim.senses.images[0], interpolation='nearest')
        axis.set_title(title)
        axis.set_xticks([0, 25, 51])
        axis.set_yticks([0, 19, 38])
    figure.suptitle('camera/image_raw (52 x 39 rgb8, horizontal field of view 0.84 rad)')
    figure.tight_layout()
    figure.savefig(out / 'senses_camera.png', dpi=80)
    plt.close(figure)


def sweep(out: Path, work: Path) -> None:
    """The manual's example sweep (in this process: the same trials as on a local cluster)."""
    shutil.rmtree(work / 'sweep_out', ignore_errors=True)
    run(BIN / 'sweep', ROOT / 'epuck_ros' / 'experiments' / 'examples' / 'avoid_seeds.yaml', '-o',
        work / 'sweep_out', '--workers', '0')
    shutil.copy(work / 'sweep_out' / 'sweep.png', out / 'sweep.png')


def fitness(out: Path, work: Path) -> None:
    """Best and mean fitness per generation of `evolve --seed 1`, from docs/images/fitness.csv."""
    from epuck_ros.evolution.cli import draw_fitness
    draw_fitness(fitness_rows(FITNESS_CSV), out / 'fitness.png')


def fitness_rows(path: Path) -> list[tuple[int, float, float]]:
    with open(path, newline='') as file:
        return [(int(row['generation']), float(row['best']), float(row['mean'])) for row in csv.DictReader(file)]


def fitness_facts(work: Path) -> list[str]:
    """The CSV is still what `evolve --seed 1` makes (its first generations, rerun), and the manual's figures."""
    run(BIN / 'evolve', '-o', work / 'evolve_check', '--seed', '1', '--generations', str(CHECKED_GENERATIONS),
        '--workers', '0')
    rows = fitness_rows(FITNESS_CSV)
    again = fitness_rows(work / 'evolve_check' / 'fitness.csv')
    if again != rows[:CHECKED_GENERATIONS]:
        return [f'docs/images/fitness.csv as evolve --seed 1 makes it today (its first generations differ: {again} '
                f'against {rows[:CHECKED_GENERATIONS]}; rerun with --evolve)']
    best = max(rows, key=lambda row: row[1])
    return [f'scored {rows[0][1]:.2f} in generation 0, {rows[50][1]:.2f} by generation 50 and {best[1]:.2f} at most '
            f'(generation {best[0]})', f'mean rose from {rows[0][2]:.2f} to {rows[50][2]:.2f} by generation 50 and '
                                       f'ended at {rows[-1][2]:.2f}']


def evolve_fully(work: Path) -> None:
    """`evolve -o OUT --seed 1` with the paper's 80 x 100: its fitness.csv becomes docs/images/fitness.csv."""
    run(BIN / 'evolve', '-o', work / 'evolve_out', '--seed', '1')
    shutil.copy(work / 'evolve_out' / 'fitness.csv', FITNESS_CSV)


LEARNED_LINE = re.compile(r'^(learned policy|random policies of its form|straight ahead, blind) +on \d+ fresh 60 s '
                          r'episodes: mean fitness (-?[0-9.]+), touching a wall or an obstacle ([0-9.]+)% of the time$',
                          re.M)
"""The example's judgement of the learned policy, as it prints it: the manual's table."""


def learned(out: Path, work: Path) -> None:
    """The manual's learning example, its picture and its judgement of the result (kept for the facts)."""
    output = run(sys.executable, ROOT / 'epuck_ros' / 'envs' / 'examples' / 'learn_avoid_cma.py', '--picture',
                 out / 'learned_avoid.png')
    (work / 'learned.txt').write_text(output)


def learned_facts(work: Path) -> list[str]:
    found = LEARNED_LINE.findall((work / 'learned.txt').read_text())
    rows = {name: (score, share) for name, score, share in found}
    return [f'| {label} | {rows[name][0]} | {rows[name][1]} % |' for name, label in (
        ('learned policy', 'learned by CMA-ES'),
        ('random policies of its form', 'random policies of the same form (most turn on the spot or back off)'),
        ('straight ahead, blind', 'straight ahead, blind'))]


def view(out: Path, work: Path) -> None:
    """The live view's screenshot, by the browser test (it writes docs/images/view.png when asked to)."""
    if out.resolve() != IMAGES.resolve():
        raise SystemExit('[pictures] view: the browser test writes docs/images/view.png only (leave out --out)')
    output = run(sys.executable, '-m', 'pytest', '-q', '-rs', 'test/test_view_browser.py', '-k', 'several_robots',
                 EPUCK_ROS_UPDATE_SCREENSHOT='1')
    if 'skipped' in output.lower() and ' passed' not in output:
        raise SystemExit(f'[pictures] view: the browser test was skipped (it needs chromium and chromedriver):\n'
                         f'{output[-800:]}')


PICTURES = [
    Picture('bag_rectangle', sample_bag('rectangle')),
    Picture('bag_swarm', sample_bag('swarm')),
    Picture('senses_line_follower', senses_run('line_follower.py', 'line_track.yaml', 30.0)),
    Picture('senses_light_seeker', senses_run('light_seeker.py', 'lit_arena.yaml', 45.0), light_seeker_facts),
    Picture('senses_find_red_box', senses_run('find_red_box.py', 'coloured_objects.yaml', 20.0), red_box_facts),
    Picture('senses_camera', camera_views),
    Picture('sweep', sweep),
    Picture('fitness', fitness, fitness_facts),
    Picture('learned_avoid', learned, learned_facts),
    Picture('view', view, compared=False),
]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    names = [picture.name for picture in PICTURES]
    parser.add_argument('--only', nargs='+', choices=names, metavar='NAME', help=f'these only: {", ".join(names)}')
    parser.add_argument('--out', type=Path, default=IMAGES, help='folder to write them in (default docs/images)')
    parser.add_argument('--check', action='store_true',
                        help='remake them in a scratch folder and compare with docs/images (and the manual)')
    parser.add_argument('--evolve', action='store_true', help='rerun evolve --seed 1 fully for fitness.csv first')
    args = parser.parse_args()
    chosen = [p for p in PICTURES if p.name in (args.only or names) and (not args.check or p.compared)]
    with tempfile.TemporaryDirectory(prefix='pictures_') as scratch:
        work = Path(scratch)
        out = work / 'remade' if args.check else args.out
        out.mkdir(parents=True, exist_ok=True)
        if args.evolve:
            evolve_fully(work)
        workers = max(1, min(len(chosen), os.cpu_count() or 1))
        with ThreadPoolExecutor(workers) as pool:   # the runs are processes of their own: one per core at once
            list(pool.map(lambda picture: made(picture, out, work), chosen))
        if args.check:
            problems = [line for picture in chosen for line in compare(picture, out, work)]
            for line in problems:
                print(f'[pictures] {line}', file=sys.stderr)
            if problems:
                raise SystemExit(f'[pictures] {len(problems)} problem(s): run python scripts/make_pictures.py (and '
                                 'update the manual\'s figures) to remake them')
            print(f'[pictures] {len(chosen)} pictures as committed, and the manual\'s figures about them')


def made(picture: Picture, out: Path, work: Path) -> None:
    picture.make(out, work)
    print(f'[pictures] {picture.name}: {out / (picture.name + ".png")}', flush=True)


def compare(picture: Picture, out: Path, work: Path) -> list[str]:
    """What is wrong with the committed picture and the manual's figures about it ([] when nothing)."""
    import numpy as np
    from matplotlib.image import imread
    problems = []
    committed, remade = IMAGES / f'{picture.name}.png', out / f'{picture.name}.png'
    if not committed.is_file():
        problems.append(f'{picture.name}: no docs/images/{committed.name}')
    else:
        old, new = imread(committed)[..., :3], imread(remade)[..., :3]
        if old.shape != new.shape:
            problems.append(f'{picture.name}: {new.shape[1]} x {new.shape[0]} px now, {old.shape[1]} x '
                            f'{old.shape[0]} committed')
        else:
            rms = float(np.sqrt(np.mean((255.0 * (old - new)) ** 2)))
            if rms > TOLERANCE:
                problems.append(f'{picture.name}: stale (RMS difference {rms:.1f} of 255, more than {TOLERANCE})')
    manual = ' '.join(' '.join(page.read_text() for page in MANUAL).split())   # a fact may be wrapped over two lines
    problems += [f'{picture.name}: the manual does not say "{fact}"' for fact in picture.facts(work)
                 if ' '.join(fact.split()) not in manual]
    return problems


if __name__ == '__main__':
    main()
