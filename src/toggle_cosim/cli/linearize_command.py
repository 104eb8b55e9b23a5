"""`toggle-cosim linearize`: a scenario's plant trimmed at a slider position and linearised there,
written as .npz or .mat (`toggle_cosim.design`; docs/designing.md)."""

from __future__ import annotations

from pathlib import Path

import click

from toggle_cosim.cli.app import InputError, check_output, main, require


def _variant(pairs: list, variant: str | None, scenario: Path):  # noqa: ANN202 - a (Run, PlantInterface)
    names = [run.variant for run, *_ in pairs]
    if variant is None:  # the first variant, as an SSP's default SSD; the result line names it
        return pairs[0]
    for pair in pairs:
        if pair[0].variant == variant:
            return pair
    raise InputError(f"{scenario}: no variant {variant!r} (--variant; choose one of {', '.join(map(str, names))})")


@main.command()
@click.argument("scenario", type=click.Path(path_type=Path))
@click.option("--x-B", "x_B", type=float, required=True, help="Position of slider B to hold, in m.")
@click.option(
    "--out", "-o", "output", type=click.Path(path_type=Path), required=True, help="The .npz or .mat file to write."
)
@click.option("--variant", default=None, help="The scenario's variant (default: its first).")
@click.option(
    "--fmu", type=click.Path(path_type=Path), default=None, help="Plant FMU (default: the scenario's fmu: key)."
)
@click.option("--output", "outputs", multiple=True, help="A recorded output to add to x_B, v_B, theta1 (repeatable).")
@click.option(
    "--coordinates",
    type=click.Choice(["manifold", "fmu"]),
    default="manifold",
    show_default=True,
    help="States: the mechanism's degree of freedom and the current, or every state of the FMU.",
)
def linearize(
    scenario: Path,
    x_B: float,
    output: Path,
    variant: str | None,
    fmu: Path | None,
    outputs: tuple[str, ...],
    coordinates: str,
) -> None:
    """Trim SCENARIO's plant with slider B at rest at --x-B and write its linear model (A, B, C, D,
    names, units, the operating point) to --out."""
    from toggle_cosim.cli.execution import load_runs
    from toggle_cosim.design.files import KINDS, SUFFIXES, write_linear_model
    from toggle_cosim.design.linearize import linearize as linearize_plant
    from toggle_cosim.design.model_exchange import ModelExchangeError
    from toggle_cosim.design.trim import TrimError, trim

    if output.suffix not in SUFFIXES:
        raise InputError(f"{output}: --out must end in .npz or .mat (the linear model's file)")
    if output.suffix == ".mat":
        require("scipy")
    check_output(output, "linear model (--out)", KINDS[output.suffix])
    run, plant, _ = _variant(load_runs([scenario], fmu), variant, scenario)
    try:
        point = trim(run, x_B, plant)
        model = linearize_plant(run, point, plant, outputs=outputs, coordinates=coordinates)  # type: ignore[arg-type]
    except (TrimError, ModelExchangeError) as error:
        raise InputError(f"{scenario}: {error}") from error
    write_linear_model(model, output)
    for warning in point.warnings:
        click.echo(f"warning: {warning}", err=True)
    poles = ", ".join(f"{p.real:.6g}{p.imag:+.6g}j" if p.imag else f"{p.real:.6g}" for p in model.eigenvalues())
    click.echo(
        f"{run.label} at x_B = {point.x_B:g} m: i_q* = {point.iq_ref:.6g} A holds it (F_E = {point.F_E:g} N, "
        f"m_B = {point.m_B:g} kg); states {', '.join(model.states)}; poles {poles} "
        f"(estimated relative error {model.relative_error:.1e})"
    )
    click.echo(f"wrote {output}")
