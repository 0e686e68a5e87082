"""Gymnasium and PettingZoo environments on the pure core.

`import epuck_ros.envs` registers `epuck_ros/Avoid-v0` (one e-puck; `gymnasium.make_vec(...,
vectorization_mode='vector_entry_point')` steps N worlds together in one process); `swarm_avoid_v0` is the
PettingZoo form, N robots in one world, each an agent.
"""
import gymnasium

from epuck_ros.envs import swarm_avoid_v0

__all__ = ['swarm_avoid_v0']

gymnasium.register(id='epuck_ros/Avoid-v0', entry_point='epuck_ros.envs.avoid:AvoidEnv',
                   vector_entry_point='epuck_ros.envs.avoid:AvoidVectorEnv')
