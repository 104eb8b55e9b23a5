"""Co-simulation: the master that steps a run's system, the plant FMU and its controller with any
parts, built from parts.

    master.simulate          one run: its system stepped by the execution
    pair_execution           the plain pair as the two-part system it is, with the pair's trace and run.json
    systems                  a run's components assembled and checked; simulate_system runs them
    execution                the Python execution: slaves stepped by the plan, observers (the trace)
    slaves                   a component as the master steps it: an FMU (FmuSlave), or a native controller
    system_loop              the plan run in C (built and cached), native controllers and FMUs alike
    system_retry             checkpoints every N samples; restore, replay, substeps on a failure
    instance_pool            FMU instances kept loaded from run to run (sweeps, tuning)
    outcome                  RunOutcome and the run record (run.json)
    summary                  RunSummary: a run's figures of merit, computed from its trace
    supervision              a run in a forked child with a wall-clock limit

Nothing is imported here, so importing a part does not import the others.
"""
