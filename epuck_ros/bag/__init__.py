"""rosbag2-compatible MCAP bags: writing, reading and inspecting runs."""
