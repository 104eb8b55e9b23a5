"""Co-simulation: the master that steps a run's system, the plant FMU and its controller with any
parts, built from parts, in three tiers (each imports only from the tiers below it):

    execution/               the execution and its kinds; it knows no run, scenario or process
        algorithm            the Python execution: slaves stepped by the plan, observers (the trace)
        slaves               a component as the master steps it: an FMU (FmuSlave), or a native controller
        system_loop          the plan run in C (built and cached), native controllers and FMUs alike
        system_natives       the built-in law and python-control systems as native kinds of that loop
        system_python        a Python controller called back from that loop
        system_retry         checkpoints every N samples; restore, replay, substeps on a failure
        instance_pool        FMU instances kept loaded from run to run (sweeps, tuning)
    master                   one run: check (checked.check_run, in the process that starts it), then
                             simulate (its system instantiated and stepped: systems.execute)
    checked                  a run checked before anything is loaded: CheckedRun
    systems                  a checked run's components instantiated and stepped (execute)
    pair_execution           the plain pair as the two-part system it is, with the pair's trace and run.json
    outcome, summary         RunOutcome and the run record (run.json); a run's figures of merit
    isolation/               the process isolation of runs
        supervision          a run in a forked child with a wall-clock limit, checked in the parent
        supervised_batch     several supervised runs at once, outcomes in order
        plant_host           a child that keeps a plant loaded and runs request after request

Nothing is imported here, so importing a part does not import the others.
"""
