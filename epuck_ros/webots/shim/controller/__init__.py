"""`controller`, as a Webots controller script imports it, for the e-puck on epuck_ros's simulator.

Only `webots_controller` puts this module on the import path (never installed as a top-level package: it
would hide a real Webots installation, and the name is someone else's on PyPI). Names of Webots' module that
this shim does not provide are refused with a message saying so.
"""
from epuck_ros.webots.devices import (
    GPS, LED, Accelerometer, Camera, Compass, Device, DistanceSensor, Gyro, InertialUnit, LightSensor, Motor,
    PositionSensor)
from epuck_ros.webots.robot import Robot

__all__ = ['Robot', 'Device', 'Motor', 'DistanceSensor', 'PositionSensor', 'LED', 'Camera', 'LightSensor',
           'Accelerometer', 'Gyro', 'GPS', 'Compass', 'InertialUnit']


def __getattr__(name: str) -> object:
    if name.startswith('_'):
        raise AttributeError(name)
    # An ImportError (not AttributeError) so that `from controller import Camera` shows this message.
    raise ImportError(f'controller.{name} is part of the Webots API but not supported by epuck_ros\'s Webots shim; '
                      f'supported: {", ".join(__all__)}', name='controller')
