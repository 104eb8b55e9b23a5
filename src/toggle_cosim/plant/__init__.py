"""The plant: the interface contract, its checks, and what a run sets on it."""
