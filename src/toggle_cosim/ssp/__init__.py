"""The study as an SSP archive, 1.0 or 2.0 (System Structure and Parameterization): the plant FMU and the
controller FMU as components (and any other FMU components of a system: a sensor, a load), their
connections, one root SSD per scenario variant (each binding
one parameter set per component), the default experiment. `writer` writes one from a scenario
file; `reader` reads a variant back into what our master runs (`run`), from the SSD and its .ssv
files only (`variants`, `bindings`, `wiring`, `as_scenario`); `checks` holds what both check (the
vendored SSP 1.0 and 2.0 schemas, bounded XML, the archive's safety), `layout` the archive's shape,
`versions` what SSP 2.0 adds, `study_record` the study's SRMD in a 2.0 SSD's MetaData. User
documentation: docs/ssp.md."""

from toggle_cosim.ssp.checks import SspError

__all__ = ["SspError"]
