"""Evolving the e-puck's obstacle avoidance as Floreano and Mondada did: a genetic algorithm over the weights
of a small recurrent network, fitness Phi = V (1 - sqrt(dv)) (1 - i) on the pure core."""
