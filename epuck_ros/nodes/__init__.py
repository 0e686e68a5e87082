"""Thin ROS 2 nodes around the pure core: they only convert messages and parameters."""
