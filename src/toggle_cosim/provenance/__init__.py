"""Provenance records: SRMD files (SSP Traceability) naming by SHA3-256 every file that shaped a
result (`srmd`), with the vendored SRMD schema (`schemas/`)."""
