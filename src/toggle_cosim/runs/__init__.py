"""Runs: the typed definition of one co-simulation, below the plant, the master and the experiments."""
