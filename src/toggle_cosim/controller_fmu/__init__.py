"""The VSC as a native FMI 2.0 / FMI 3.0 Co-Simulation FMU (`ToggleVSC`), generated from the
law's one definition (`control.laws`, `control.nominal`) by the translator the compiled loop
uses, with a small generic C shell for a sampled controller (docs/controller-fmu.md).

variables.py (the variables, from LawParameters' metadata) --source.py--> C
    --model_description.py--> modelDescription.xml --build.py--> .fmu
"""

from __future__ import annotations

from toggle_cosim.controller_fmu.build import ControllerFMU, build_controller_fmu

__all__ = ["ControllerFMU", "build_controller_fmu"]
