"""A linear model (`LinearModel.as_arrays`) written as a NumPy .npz or a MATLAB .mat file
(scipy.io.savemat, the extra [design]), through the project's unique-temporary-name writer."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from toggle_cosim.design.linearize import LinearModel
from toggle_cosim.files.outputs import MAT, NPZ, OutputKind, write_file

__all__ = ["SUFFIXES", "write_linear_model"]

SUFFIXES = (".npz", ".mat")
KINDS: dict[str, OutputKind] = {".npz": NPZ, ".mat": MAT}  # what each suffix's file is (only that is replaced)


def write_linear_model(model: LinearModel, path: Path) -> Path:
    """Write A, B, C, D, the names, units and the operating point to `path` (.npz or .mat)."""
    arrays = model.as_arrays()
    if path.suffix == ".mat":
        from scipy.io import savemat

        return write_file(path, lambda stream: savemat(stream, arrays), binary=True, what="linear model", kind=MAT)
    if path.suffix == ".npz":
        return write_file(path, lambda stream: np.savez(stream, **arrays), binary=True, what="linear model", kind=NPZ)
    raise ValueError(f"{path}: write a linear model to a .npz or .mat file")
