"""The study as an SSP 1.0 archive (System Structure and Parameterization): the plant FMU and the
controller FMU as components, their connections, one parameter set per scenario variant, the
default experiment. `writer` writes one from a scenario file, `reader` reads one back into what
our master runs (`run`), `checks` holds what both check (the vendored SSP 1.0 schemas, the
archive's safety), `layout` the fixed shape of the archive. User documentation: docs/ssp.md."""

from toggle_cosim.ssp.checks import SspError

__all__ = ["SspError"]
