"""The evolved controller's network, after Floreano and Mondada (1994): one layer, eight IR inputs and a bias to two
motor neurons, each motor neuron also fed back both motor outputs of the previous step (self and lateral recurrent
connections); tanh outputs are the wheel speeds as fractions of the maximum.

A genome is the 2 x 11 weights, row by row: for the left then the right neuron, the eight IR weights, the bias,
the weight of the previous left output, the weight of the previous right output.
"""
from __future__ import annotations

import numpy as np

INPUTS = 8
GENES = 2 * (INPUTS + 1 + 2)
"""Weights in a genome: 22."""


def outputs(genomes: np.ndarray, activation: np.ndarray, previous: np.ndarray) -> np.ndarray:
    """Wheel speeds (P, 2) in (-1, 1) of P networks `genomes` (P, 22) given IR activations (P, 8) and their
    previous outputs (P, 2)."""
    weights = genomes.reshape(-1, 2, INPUTS + 3)
    inputs = np.concatenate([activation, np.ones((len(activation), 1)), previous], axis=1)   # (P, 11)
    return np.tanh(np.einsum('pki,pi->pk', weights, inputs))
