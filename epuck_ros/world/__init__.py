"""The world the e-puck drives in: a walled rectangular arena with boxes and cylinders, read from YAML.

One module per job; import from here (`from epuck_ros.world import World, load_world`), which names them all:

- `data`: what a world holds (World, Box, Cylinder, RobotStart with its TurretDevices) and the default world;
- `loading`: world files read and checked field by field (the file format is in its docstring);
- `geometry`, `cells`, `raycast`, `collisions`: the obstacles prepared once, the grids that keep a query's cost
  flat, ray casting, and discs pushed out of what they overlap;
- `placement`: robots placed by seed for swarms.
"""
from epuck_ros.world.data import (ONE_ROBOT, ROBOT_NAME, ROBOT_NAME_MAX, TURRET_KINDS, Box, Cylinder, RobotStart,
                                  TurretDevice, World, WorldError, default_world)
from epuck_ros.world.geometry import CONTACT_TOLERANCE, ray_circle
from epuck_ros.world.loading import (MAX_FILE_BYTES, MAX_MAGNITUDE, MAX_NESTING, load_world, world_from_dict,
                                     world_from_yaml)
from epuck_ros.world.placement import ROBOT_GAP, place_robots, placed_names

__all__ = ['CONTACT_TOLERANCE', 'MAX_FILE_BYTES', 'MAX_MAGNITUDE', 'MAX_NESTING', 'ONE_ROBOT', 'ROBOT_GAP',
           'ROBOT_NAME', 'ROBOT_NAME_MAX', 'TURRET_KINDS', 'Box', 'Cylinder', 'RobotStart', 'TurretDevice', 'World',
           'WorldError', 'default_world',
           'load_world', 'place_robots', 'placed_names', 'ray_circle', 'world_from_dict', 'world_from_yaml']
