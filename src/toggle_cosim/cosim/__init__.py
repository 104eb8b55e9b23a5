"""Co-simulation: the master that steps a plant FMU with the discrete VSC, built from parts.

    session.PlantSession     one FMU instance, public API (life cycle, I/O, doStep, state)
    recorder.Recorder        the trace buffer (own array, or a shared disk-backed one)
    recorder.ProgressHook    a step hook: progress reports every so many samples
    stepper                  the Stepper protocol: PythonStepper, CompiledStepper, HandOver
    compiled_loop            the generated C loop (built and cached), driven by CompiledStepper
    retry.CheckpointPolicy   checkpoints every N samples; restore, replay, substeps on a failure
    system_retry             the same for a system's run, every component's state saved
    master.simulate          assembles these parts for one run
    outcome                  RunOutcome and the run record (run.json)
    summary                  RunSummary: a run's figures of merit, computed from its trace
    supervision              a run in a forked child with a wall-clock limit

Nothing is imported here, so importing a part does not import the others.
"""
