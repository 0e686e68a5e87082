"""The live view: a page served from the package (static/), the state it draws (state.py), its server (server.py).

The ROS side is `epuck_ros.nodes.view_node`; nothing here imports rclpy.
"""
