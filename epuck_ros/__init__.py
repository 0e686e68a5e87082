"""epuck_ros: a fast, deterministic e-puck simulator, the course behaviours and MCAP tools."""
