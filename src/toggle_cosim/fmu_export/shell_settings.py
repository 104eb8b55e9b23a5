"""The one table of the shell's own settings, statistics and log categories.

Both forms come from here: modelDescription.xml (model_description.py) and the C header
`md_settings.h` the shell includes (written into every FMU's sources/ by package.py, see
`settings_header`). Nothing in the C repeats a name, a default or a log category.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class ShellSetting:
    """A setting of the FMU's integrator, exposed as a tunable Real / Float64 parameter."""

    name: str
    c_name: str  # the index constant in C
    start: float
    unit: str
    description: str


@dataclass(frozen=True)
class ShellStatistic:
    """An integrator statistic, a local discrete Integer / Int64 variable."""

    name: str
    c_name: str
    description: str


@dataclass(frozen=True)
class LogCategory:
    name: str
    c_name: str
    description: str


# Value references nvars + 0, 1, 2, in this order (shell/instance.h). The ranges are checked
# in solver.c (md_solver_set_setting).
SHELL_SETTINGS = (
    ShellSetting(
        "solver.relTol",
        "MD_SETTING_RELTOL",
        1e-8,
        "1",
        "Relative error tolerance of the FMU's internal Dormand-Prince 5(4) integrator, (0, 0.1]",
    ),
    ShellSetting(
        "solver.absTol",
        "MD_SETTING_ABSTOL",
        1e-10,
        "1",
        "Absolute error tolerance of the internal integrator, per state, > 0",
    ),
    ShellSetting(
        "solver.maxStep", "MD_SETTING_MAXSTEP", 0.0, "s", "Largest internal integration step; 0 means unbounded"
    ),
)

SHELL_STATISTICS = (
    ShellStatistic(
        "solver.steps",
        "MD_STATISTIC_STEPS",
        "Accepted integrator steps since instantiation (Model Exchange: the importer's completed integrator steps)",
    ),
    ShellStatistic(
        "solver.rejectedSteps",
        "MD_STATISTIC_REJECTED",
        "Rejected integrator steps since instantiation (error test failed or non-finite values; "
        "0 under Model Exchange)",
    ),
    ShellStatistic(
        "solver.events",
        "MD_STATISTIC_EVENTS",
        "State events handled since instantiation (transitions, event iteration included)",
    ),
)

# The log categories of shell/fmi2.c and shell/fmi3.c, in their order.
FMI2_LOG_CATEGORIES = (
    LogCategory("logEvents", "MD_FMI2_LOG_EVENTS", "One line per state event: time, indicator and kind"),
    LogCategory(
        "logStatusError", "MD_FMI2_LOG_STATUS_ERROR", "Calls that return a status other than fmi2OK, with the reason"
    ),
    LogCategory("logAll", "MD_FMI2_LOG_ALL", "Everything, including integrator statistics per communication step"),
)
FMI3_LOG_CATEGORIES = (
    LogCategory("logEvents", "MD_FMI3_LOG_EVENTS", "One line per state event: time, indicator and kind"),
    LogCategory("logStatusWarning", "MD_FMI3_LOG_STATUS_WARNING", "Calls that return fmi3Warning, with the reason"),
    LogCategory(
        "logStatusError", "MD_FMI3_LOG_STATUS_ERROR", "Calls that return fmi3Error, with the reason (always reported)"
    ),
    LogCategory("logAll", "MD_FMI3_LOG_ALL", "Everything, including integrator statistics per communication step"),
)

HEADER_NAME = "md_settings.h"


def _c_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _enum(items: tuple, count: str) -> str:
    return (
        "enum { " + ", ".join(f"{item.c_name} = {k}" for k, item in enumerate(items)) + f", {count} = {len(items)} }};"
    )


def settings_header() -> str:
    """md_settings.h: the tables above as C."""
    settings = ",\n    ".join(
        f"{{{_c_string(s.name)}, {s.start!r}, {_c_string(s.unit)}, {_c_string(s.description)}}}" for s in SHELL_SETTINGS
    )
    lines = [
        f"/* {HEADER_NAME}: written by toggle_cosim.fmu_export.shell_settings from its tables (the",
        " * modelDescription.xml is written from the same tables). Do not edit. */",
        "#ifndef MD_SETTINGS_H",
        "#define MD_SETTINGS_H",
        "",
        f"#define MD_SHELL_NREAL {len(SHELL_SETTINGS)}",
        _enum(SHELL_SETTINGS, "MD_NSETTINGS"),
        "/* {name, start, unit, description} in value-reference order, for md_setting[] */",
        f"#define MD_SHELL_SETTINGS_TABLE {{ \\\n    {settings.replace(chr(10), ' ' + chr(92) + chr(10))} }}",
        "",
        _enum(SHELL_STATISTICS, "MD_NSTATISTICS"),
        "",
        _enum(FMI2_LOG_CATEGORIES, "MD_FMI2_NLOG"),
        "#define MD_FMI2_LOG_NAMES {" + ", ".join(_c_string(c.name) for c in FMI2_LOG_CATEGORIES) + "}",
        _enum(FMI3_LOG_CATEGORIES, "MD_FMI3_NLOG"),
        "#define MD_FMI3_LOG_NAMES {" + ", ".join(_c_string(c.name) for c in FMI3_LOG_CATEGORIES) + "}",
        "",
        "#endif",
        "",
    ]
    return "\n".join(lines)
