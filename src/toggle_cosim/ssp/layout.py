"""The shape of the SSPs toggle-cosim writes: member names, component names, namespaces, and
how variants and parameter sets are named and bound (SSP 1.0.1, section 3 "Packaging" and
section 5 "ParameterBindings"; docs/ssp.md).

Variants. Every scenario variant is one root SSD, as the standard defines variants:
`SystemStructure.ssd` is the first variant (the default every SSP tool runs), each other variant
is `<variant>.ssd` beside it (`ssd_member`). Each root SSD's `name` is its variant's name (unique
in the archive; a scenario without variants: `SINGLE_SET`) and its System's `name` the
scenario's.

Parameter sets. Each root SSD binds exactly one parameter set per component: `.ssv` files, one per
component (`ssv_member`), each a ParameterSet named after the variant holding exactly that
component's values. The standard applies every binding of a component, later ones taking
priority, so one binding each is the only layout that every master reads alike: libcosim (which
applies a component's first binding) and Ecos (which applies a set named at init: the variant's
name) included. One file per component rather than one per set: a binding applies every
parameter of its file whose name the component has, so a shared file would set the controller's
nominal model on a plant that has variables of the same names.
"""

from __future__ import annotations

from toggle_cosim.control.protocol import COMMAND_COLUMNS

SSD_MEMBER = "SystemStructure.ssd"  # the default variant
SSD_SUFFIX = ".ssd"
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

# Our annotation on each root SSD: the scenario file, variant and document it was written from. It
# describes only: no reader of ours takes anything from it
ANNOTATION_TYPE = "org.toggle-cosim.scenario"
# the annotation of the SSPs of earlier versions, which stacked one binding per set on each component
# (a conforming master applies them all, the last taking priority): such an SSP is refused
OLD_ANNOTATION_TYPE = "org.toggle-cosim.experiment"
TOGGLE_NS = "https://github.com/toggle-cosim/toggle-cosim/ssp/experiment"


def fmu_member(file_name: str) -> str:
    """The archive member of a component's FMU."""
    return f"{RESOURCES}/{file_name}"


def ssd_member(index: int, variant: str) -> str:
    """The root SSD of the variant at `index` in the scenario's order: the first is the default."""
    return SSD_MEMBER if index == 0 else f"{variant}{SSD_SUFFIX}"


def ssv_member(parameter_set: str, component: str) -> str:
    """The archive member of one component's values in one parameter set."""
    return f"{RESOURCES}/{parameter_set}.{component}.ssv"


def set_name(variant: str | None) -> str:
    """The parameter set of a scenario variant."""
    return SINGLE_SET if variant is None else variant
