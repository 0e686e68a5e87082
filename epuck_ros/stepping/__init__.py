"""The parts `Simulation` is made of: the robots' state arrays, two paired steppers, and the sensor parts.

`one_robot.OneRobotStepper` (plain floats) and `swarm.SwarmStepper` (NumPy, robot pairs) move the robots by
the same rule, as Gymnasium keeps CartPoleEnv and CartPoleVectorEnv side by side; each offers `step(state)`
and `reset(state)` and reads the sensor parts (`ir_ring.IrRing`) after moving. A new sensor is a part with a
`sense_one` and a `sense_many` path and its own readings, composed by both steppers.
"""
