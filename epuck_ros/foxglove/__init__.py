"""Foxglove without ROS: where the bridge serves (`address`) and the layout shipped in docs/ (`layout`).

The bridge itself is a node: `epuck_ros.nodes.foxglove_node` (the `foxglove` executable).
"""
