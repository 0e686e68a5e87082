"""The README's camera picture: what the e-puck's camera sees (52 x 39, drawn 8 times larger) in three shipped
worlds, rendered by the pure core (epuck_ros.sensors.camera). Run: python docs/senses_pictures.py [OUTPUT.png]"""
from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402

from epuck_ros.simulation import Simulation  # noqa: E402
from epuck_ros.world import load_world  # noqa: E402
from epuck_ros.world.data import RobotStart  # noqa: E402

WORLDS = Path(__file__).resolve().parents[1] / 'epuck_ros' / 'worlds'
VIEWS = [('coloured_objects.yaml', (-0.15, -0.1, 0.55), 'coloured objects: the red box ahead'),
         ('line_track.yaml', (-0.03, -0.25, 0.0), 'line track: the oval ahead'),
         ('lit_arena.yaml', (-0.2, -0.2, 0.6), 'lit arena: the yellow disc under the light')]


def main() -> None:
    output = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent / 'images' / 'senses_camera.png'
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


if __name__ == '__main__':
    main()
