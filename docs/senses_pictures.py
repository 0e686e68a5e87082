"""The README's senses pictures, made from the pure core: what the e-puck's camera sees (52 x 39, drawn 8 times
larger) in three shipped worlds (senses_camera.png), and the line follower's 30 s on the line track, run headless
and recorded, as `bag plot` draws it (senses_line_follower.png).
Run: python docs/senses_pictures.py [FOLDER]   (default: docs/images)"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402

from epuck_ros.bag.cli import main as bag  # noqa: E402
from epuck_ros.experiments.trial import Script, Trial, run_trial  # noqa: E402
from epuck_ros.simulation import Simulation  # noqa: E402
from epuck_ros.world import load_world  # noqa: E402
from epuck_ros.world.data import RobotStart  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
WORLDS = ROOT / 'epuck_ros' / 'worlds'
EXAMPLES = ROOT / 'epuck_ros' / 'webots' / 'examples'
VIEWS = [('coloured_objects.yaml', (-0.15, -0.1, 0.55), 'coloured objects: the red box ahead'),
         ('line_track.yaml', (-0.03, -0.25, 0.0), 'line track: the oval ahead'),
         ('lit_arena.yaml', (-0.2, -0.2, 0.6), 'lit arena: the yellow disc under the light')]


def camera_views(output: Path) -> None:
    figure, axes = plt.subplots(1, len(VIEWS), figsize=(15, 4.2))
    for axis, (name, pose, title) in zip(axes, VIEWS):
        world = load_world(WORLDS / name)
        sim = Simulation(world.with_robots([RobotStart('epuck', *pose)]), noise=False)
        sim.senses.want('camera', [0])
        axis.imshow(sim.senses.images[0], interpolation='nearest')
        axis.set_title(title)
        axis.set_xticks([0, 25, 51])
        axis.set_yticks([0, 19, 38])
    figure.suptitle('camera/image_raw (52 x 39 rgb8, horizontal field of view 0.84 rad)')
    figure.tight_layout()
    figure.savefig(output, dpi=80)
    print(f'wrote {output}')


def line_follower(output: Path) -> None:
    """`webots_controller line_follower.py --headless --world line_track.yaml --duration 30 --record`, then
    `bag plot`: the same run as bringup's in lockstep."""
    with tempfile.TemporaryDirectory() as scratch:
        bag_folder = Path(scratch) / 'line_follower'
        [row] = run_trial(Trial(Script(str(EXAMPLES / 'line_follower.py')), world=str(WORLDS / 'line_track.yaml'),
                                duration=30.0, record=str(bag_folder)))
        if row['error']:
            raise SystemExit(f'line_follower.py failed: {row["error"]}')
        bag(['plot', str(bag_folder), '-o', str(output)])


def main() -> None:
    folder = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent / 'images'
    folder.mkdir(parents=True, exist_ok=True)
    camera_views(folder / 'senses_camera.png')
    line_follower(folder / 'senses_line_follower.png')


if __name__ == '__main__':
    main()
