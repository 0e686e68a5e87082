"""Testing helpers for users' CI: the `epuck_sim` pytest fixture (plugin.py) and the simulator it drives."""
