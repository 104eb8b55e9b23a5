"""Designing a controller on the plant: trim and linearise the plant FMU (docs/designing.md).

model_exchange.py  the plant FMU opened through Model Exchange: states, derivatives, outputs
roles.py           which of the shipped plant's states are the coordinate, rate, current
differences.py     Richardson-extrapolated central differences with an error estimate (pure)
trim.py            `trim`, `OperatingPoint`: slider B held at rest at a position
linearize.py       `linearize`, `LinearModel`: A, B, C, D, names, units, a python-control StateSpace
files.py           a linear model written as .npz or .mat
"""
