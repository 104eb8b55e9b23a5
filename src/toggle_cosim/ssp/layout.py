"""The fixed shape of the SSPs toggle-cosim writes and reads: member names, component names,
namespaces, the annotation of our own, and how parameter sets are named and bound.

Parameter sets. Every scenario variant is one parameter set, named after the variant (a scenario
without variants: one set named `SINGLE_SET`). A set is two `.ssv` files, one per component
(`ssv_member`), each a ParameterSet of that name holding exactly that component's values. Each
component carries one ParameterBinding per set, in the scenario's variant order, so:

* the default set is the scenario's first variant: the first binding of each component, which is
  what libcosim applies when no set is named (its "" set) and what `reader.read_ssp` takes when
  none is given;
* another set is chosen by its name, the ParameterSet `name` of the .ssv files (libcosim's and
  ecospy's named parameter sets, `toggle-cosim run study.ssp --parameter-set NAME`).

One file per component rather than one per set: a binding applies every parameter of its file
whose name the component has, without a prefix in libcosim, so a shared file would set the
controller's nominal model on a plant that has variables of the same names.
"""

from __future__ import annotations

from toggle_cosim.control.protocol import COMMAND_COLUMNS

SSD_MEMBER = "SystemStructure.ssd"
RESOURCES = "resources"
PLANT, CONTROLLER = "plant", "controller"  # the components' names
COMMAND, EXTERNAL_FORCE = COMMAND_COLUMNS  # the controller's output that drives the plant; the plant input
# set from the parameter set (no system-level connector)
FMU_TYPE = "application/x-fmu-sharedlibrary"
SINGLE_SET = "run"  # the parameter set of a scenario without variants (its output folder's name too)

SSD_NS = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC_NS = "http://ssp-standard.org/SSP1/SystemStructureCommon"
SSV_NS = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
NAMESPACES = {"ssd": SSD_NS, "ssc": SSC_NS, "ssv": SSV_NS}

# The step size for libcosim (its fixed-step algorithm, read from the DefaultExperiment's annotation
# of this type; libcosim reads the element names with the prefix osp:)
OSP_ANNOTATION_TYPE = "com.opensimulationplatform"
OSP_NS = "http://opensimulationplatform.com/SSP/OSPAnnotations"

# Our annotation on the SSD: T_s and, per parameter set, the scenario document it was written from
ANNOTATION_TYPE = "org.toggle-cosim.experiment"
TOGGLE_NS = "https://github.com/toggle-cosim/toggle-cosim/ssp/experiment"


def fmu_member(file_name: str) -> str:
    """The archive member of a component's FMU."""
    return f"{RESOURCES}/{file_name}"


def ssv_member(parameter_set: str, component: str) -> str:
    """The archive member of one component's values in one parameter set."""
    return f"{RESOURCES}/{parameter_set}.{component}.ssv"


def set_name(variant: str | None) -> str:
    """The parameter set of a scenario variant."""
    return SINGLE_SET if variant is None else variant
