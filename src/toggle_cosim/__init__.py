"""toggle-cosim: the Fung, Wu and Chen (2001) PMLSM toggle mechanism as an FMU plus a VSC master.

The Python API, in one import (docs/python-api.md):

    import toggle_cosim as tc

    fig4 = tc.load_scenario("scenarios/fig4_nominal.yaml")    # runs by variant name
    result = tc.simulate(fig4["friction"], tc.plant_fmu())     # supervised: a plant crash fails the run
    df = result.to_dataframe()                                  # df.attrs["units"]
    assert tc.compare(result, tc.stored_reference(result.run))

Each name is imported from its module (`toggle_cosim.api`) on first use, so importing the
package, as the command line does, costs nothing more.
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

# every public name and the module that defines it
_PUBLIC = {
    "load_scenario": "toggle_cosim.api.scenarios",
    "scenario": "toggle_cosim.api.scenarios",
    "Scenario": "toggle_cosim.api.scenarios",
    "ScenarioError": "toggle_cosim.api.scenarios",
    "simulate": "toggle_cosim.api.simulation",
    "Result": "toggle_cosim.api.result",
    "RunInterrupted": "toggle_cosim.api.result",
    "compare": "toggle_cosim.api.comparison",
    "Comparison": "toggle_cosim.api.comparison",
    "CompareInputError": "toggle_cosim.api.comparison",
    "verify_fmu": "toggle_cosim.api.verification",
    "Verification": "toggle_cosim.fmi_ls_ref.verify",
    "LsRefError": "toggle_cosim.fmi_ls_ref.manifest",
    "plot": "toggle_cosim.api.plotting",
    "sweep": "toggle_cosim.api.sweeping",
    "SweepError": "toggle_cosim.api.sweeping",
    "shipped_scenarios": "toggle_cosim.api.project",
    "plant_fmu": "toggle_cosim.api.project",
    "stored_reference": "toggle_cosim.api.project",
    "ContractError": "toggle_cosim.plant.contract",
    "Run": "toggle_cosim.runs.definition",
    "RunSummary": "toggle_cosim.cosim.summary",
    "trim": "toggle_cosim.api.design",
    "linearize": "toggle_cosim.api.design",
    "OperatingPoint": "toggle_cosim.api.design",
    "LinearModel": "toggle_cosim.api.design",
    "TrimError": "toggle_cosim.api.design",
    "tune": "toggle_cosim.api.tuning",
    "TuneError": "toggle_cosim.api.tuning",
    "TuneResult": "toggle_cosim.api.tuning",
    "DiscreteSystemController": "toggle_cosim.control.lti",
}
__all__ = ["__version__", *_PUBLIC]


def __getattr__(name: str) -> object:
    module = _PUBLIC.get(name)
    if module is None:
        raise AttributeError(f"module 'toggle_cosim' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # found directly from now on
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_PUBLIC})
