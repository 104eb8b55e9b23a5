"""Physics in Python: parameters, the PMLSM thrust constant, the mechanism's kinematics."""
