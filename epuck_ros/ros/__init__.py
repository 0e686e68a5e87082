"""The ROS plumbing the nodes share: QoS profiles, messages as exact bytes, a robot's ports (topics, frames), the
acknowledgement window, parameters, spinning and shutdown, the domain watch. The executables' nodes are in `nodes/`."""
