"""The public Python API, one module per concern; use it as `import toggle_cosim as tc`.

`toggle_cosim/__init__.py` names every public object and the module here that defines it, and
imports that module on first use, so `import toggle_cosim` (and the command line) stays cheap.

* `scenarios.py`  `load_scenario`, `scenario`, `Scenario`: scenario files or dicts -> runs by variant
* `project.py`    `shipped_scenarios`, `plant_fmu`, `stored_reference`: the project's own files
* `simulation.py` `simulate`: one run, supervised (a forked child) or in this process
* `result.py`     `Result`, `RunInterrupted`: a run's trace, status, record and figures of merit
* `units.py`      the units of a trace's columns, from the plant FMU's modelDescription
* `comparison.py` `compare`, `Comparison`: the funnel comparison against a reference
* `verification.py` `verify_fmu`: an FMU run against the references it carries (FMI-LS-REF)
* `sweeping.py`   `sweep`: a parameter sweep's results table as a DataFrame
* `design.py`     `trim`, `linearize`: an operating point and the linear model there (python-control)
* `plotting.py`   `plot`: chosen variables of any runs overlaid, around a reference's funnel
* `tuning.py`     `tune`: a controller's parameters tuned for the worst case of a robustness map
"""
