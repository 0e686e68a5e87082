"""The Foxglove layout shipped as docs/foxglove_layout.json: the 3D scene (the e-puck from robot_description and
TF, the arena from world_markers), the camera, plots of odometry against ground truth and of the proximity sensors,
for the one-robot simulation (`bringup ... --foxglove`, `sim` + `foxglove`).

The file is in the form the Foxglove app exports and imports (Layout, Import from file): panels by id in
`configById`, their arrangement in `layout`. Each panel's own settings are written through the Foxglove SDK's
layout types (`foxglove.layouts`, generated from the app's panel schemas), so their keys are the app's, not
guessed here. `python -m epuck_ros.foxglove.layout [FILE]` writes it (default docs/foxglove_layout.json).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import foxglove.layouts as fl

from epuck_ros.model import SENSOR_NAMES

DOCS_FILE = Path(__file__).resolve().parents[2] / 'docs' / 'foxglove_layout.json'
TOPICS = {'description': '/robot_description', 'markers': '/world_markers', 'image': '/camera/image_raw',
          'camera_info': '/camera/camera_info', 'odom': '/odom', 'truth': '/ground_truth', 'proximity': '/proximity'}
"""The one-robot simulation's topics the layout shows (test_foxglove checks each against a running simulator)."""


def _config(settings: Any, title: str) -> dict[str, Any]:
    """A panel's settings as the app stores them: the SDK type's JSON (unset fields left out), and its title."""
    return {**json.loads(settings.to_json()), 'foxglovePanelTitle': title}


def _split(direction: str, first: object, second: object, percentage: float) -> dict[str, Any]:
    return {'direction': direction, 'first': first, 'second': second, 'splitPercentage': percentage}


def layout() -> dict[str, Any]:
    """The layout as the app's JSON."""
    scene = fl.ThreeDeeConfig(
        follow_tf='base_link', follow_mode='follow-position',
        camera_state=fl.ThreeDeeCameraState(distance=1.2, perspective=True, phi=50.0, theta_offset=45.0,
                                            target_offset=(0.0, 0.0, 0.0)),
        layers={'grid': fl.BaseRendererGridLayerSettings(visible=True, frame_id='world', size=1.0, divisions=10,
                                                         instance_id='grid'),
                'epuck': fl.BaseRendererUrdfLayerSettings(visible=True, source_type='topic',
                                                          topic=TOPICS['description'], label='e-puck',
                                                          instance_id='epuck')},
        topics={TOPICS['markers']: fl.BaseRendererRosMarkerTopicSettings(visible=True)})
    camera = fl.ImageConfig(image_mode=fl.ImageModeConfig(image_topic=TOPICS['image'],
                                                          calibration_topic=TOPICS['camera_info']))
    odometry = fl.PlotConfig(paths=[
        fl.PlotSeries(value=f'{TOPICS[topic]}.pose.pose.position.{axis}', label=f'{topic} {axis}', enabled=True,
                      timestamp_method='headerStamp')
        for topic in ('odom', 'truth') for axis in 'xy'])
    proximity = fl.PlotConfig(paths=[
        fl.PlotSeries(value=f'{TOPICS["proximity"]}{{header.frame_id=="{sensor}"}}.range', label=sensor,
                      enabled=True, timestamp_method='headerStamp')
        for sensor in SENSOR_NAMES])
    panels = {'3D!epuck': _config(scene, 'e-puck (robot_description, TF, world_markers)'),
              'Image!camera': _config(camera, 'camera'),
              'Plot!odometry': _config(odometry, 'odometry against ground truth (m)'),
              'Plot!proximity': _config(proximity, 'proximity (m; gaps: nothing within 7 cm)')}
    arrangement = _split('row', '3D!epuck', _split('column', 'Image!camera',
                                                   _split('column', 'Plot!odometry', 'Plot!proximity', 50), 34), 55)
    return {'configById': panels, 'globalVariables': {}, 'userNodes': {}, 'playbackConfig': {'speed': 1},
            'layout': arrangement}


def layout_text() -> str:
    return json.dumps(layout(), indent=2) + '\n'


def main(argv: list[str] | None = None) -> None:
    args = sys.argv[1:] if argv is None else argv
    target = Path(args[0]) if args else DOCS_FILE
    target.write_text(layout_text(), encoding='utf-8')
    print(f'wrote {target}')


if __name__ == '__main__':
    main()
