"""Webots controllers on the simulator: the `webots_controller` runner and its `controller` shim.

`devices` holds the e-puck's Webots devices as plain objects (no ROS), `link` the controller's one rclpy node,
`robot` the `Robot` class a controller script creates, `runner` the executable. `shim/controller` is the module
a script imports (`from controller import Robot`); only the runner puts it on the import path.
"""
