"""Write scenarios/measured_load.csv: a load that looks measured (a die-contact force sampled at
1 kHz by a load cell), made once from a fixed seed so the file and its reference never change.

The force is zero until contact at 0.30 s, rises over 60 ms (a smooth cosine edge) to about
80 N with a 12 Hz ring that decays in 0.1 s, and carries load-cell noise (0.5 N RMS) and the
cell's 0.1 N resolution. Run: python benchmarks/measured_load.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

OUT = Path(__file__).resolve().parents[1] / "scenarios" / "measured_load.csv"
RATE = 1000.0  # Hz
T_END = 1.5  # s, the scenario's t_end (the table covers it)


def measured_load(seed: int = 2001) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(int(round(T_END * RATE)) + 1) / RATE
    contact, rise, level = 0.30, 0.06, 80.0
    edge = np.clip((t - contact) / rise, 0.0, 1.0)
    force = level * 0.5 * (1.0 - np.cos(np.pi * edge))
    after = np.clip(t - contact - rise, 0.0, None)
    force += np.where(t > contact + rise, 6.0 * np.sin(2 * np.pi * 12.0 * after) * np.exp(-after / 0.1), 0.0)
    noise = np.random.default_rng(seed).normal(0.0, 0.5, t.size)
    force = np.where(t >= contact, np.maximum(force + noise, 0.0), 0.0)  # a contact only pushes
    return t, np.round(force, 1)  # the cell's resolution


def main() -> None:
    t, force = measured_load()
    lines = ["time [s],F_E [N]", *(f"{a:.3f},{b:.1f}" for a, b in zip(t, force, strict=True))]
    OUT.write_text("\n".join(lines) + "\n", encoding="utf-8")
    print(f"wrote {OUT} ({t.size} rows)")


if __name__ == "__main__":
    main()
