"""FMI-LS-REF (the FMI layered standard for related files, 1.0.0-alpha.1): files carried inside an
FMU under `extra/org.fmi-standard.fmi-ls-ref/`, listed with their roles in `fmi-ls-manifest.xml`.

`manifest.py` writes, reads and checks the manifest (every member it names present, its SHA3-256
checksum matching), `experiments.py` the experiment documents, `pack.py` adds files to an FMU
without touching its other members, `verify.py` runs the experiments an FMU carries and compares
them with the references it carries. User page: docs/verification.md.
"""
