"""The executables' nodes (sim, the behaviours, record, play, view, teleop, foxglove): thin ROS 2 nodes around the
pure core that only convert messages and parameters; what they share is in `epuck_ros.ros`."""
