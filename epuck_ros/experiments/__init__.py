"""Experiments without ROS: one headless trial on the pure core (`trial`), sweeps of many on Dask (`cli`)."""
