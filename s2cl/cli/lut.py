"""``s2cl lut build``: the atmosphere look-up table, rebuilt with 6S (:mod:`s2cl.atmos.lut_build`)."""

from __future__ import annotations

import shlex
from typing import Any

import click

from s2cl.atmos.sixs_profiles import PROFILES

#: the command that builds a LUT, as the provenance of the LUTs it writes records it
BUILD_COMMAND = "s2cl lut build"


@click.group()
def lut() -> None:
    """The atmosphere look-up table: rebuild it with 6S (`s2cl lut build -o FILE`)."""


@lut.command("build")
@click.option("-o", "--output", type=click.Path(dir_okay=False), required=True, help="LUT file to write (.npz).")
@click.option("-j", "--workers", type=click.IntRange(1, 64), default=2, show_default=True, help="6S processes.")
@click.option("--profiles", default=",".join(PROFILES), show_default=True, help="Comma-separated profiles.")
@click.option("--aot", "aot", default=None, help="AOT550 nodes, comma-separated, first 0 [default: shipped].")
@click.option("--sza", "sza", default=None, help="Solar zenith nodes (deg), comma-separated [default: shipped].")
@click.option("--water-vapour", "wv", default=None, help="Water-vapour nodes (g/cm2) at the reference zenith.")
@click.option("--wavelengths", default="400,2500", show_default=True, help="First,last wavelength in nm (2.5 nm grid).")
@click.option("--quiet", "-q", is_flag=True, help="No progress output.")
def build(output: str, workers: int, profiles: str, aot: str | None, sza: str | None, wv: str | None,
          wavelengths: str, quiet: bool) -> None:
    """Build s2cl's atmosphere look-up table with 6S (needs `pip install "s2cl[sixs]"` and libgfortran5)."""
    from s2cl.atmos.lut_build import build_lut

    axes = _axes(profiles, aot, sza, wv, wavelengths)
    command = _recorded_command(click.get_current_context())
    report = build_lut(output, axes, workers=workers, progress=not quiet, command=command)
    stages = ", ".join(f"{k} {report.stage_runs[k]} runs in {v:.0f} s" for k, v in report.stage_seconds.items())
    click.echo(f"wrote {report.path}: {report.runs} 6S runs, {report.seconds:.0f} s ({stages})")


def _axes(profiles: str, aot: str | None, sza: str | None, wv: str | None, wavelengths: str) -> Any:
    """The LUT's axes from the options (shipped nodes where an option is not given)."""
    from s2cl.atmos.lut_axes import LUTAxes

    kwargs: dict = {"profiles": tuple(p.strip() for p in profiles.split(",") if p.strip())}
    for key, text in (("aot550", aot), ("solar_zenith", sza), ("water_vapour", wv)):
        values = _floats(text)
        if values is not None:
            kwargs[key] = values
    lo_hi = _floats(wavelengths)
    if lo_hi is None or len(lo_hi) != 2:
        raise click.BadParameter("needs two numbers: first,last", param_hint="--wavelengths")
    kwargs["wavelength_range_nm"] = lo_hi
    return LUTAxes(**kwargs)


def _floats(text: str | None) -> tuple[float, ...] | None:
    """Comma-separated numbers; ``None`` stays ``None`` (option not given)."""
    if text is None:
        return None
    try:
        return tuple(float(x) for x in text.split(",") if x.strip())
    except ValueError as err:
        raise click.BadParameter(f"expected comma-separated numbers, got {text!r}") from err


def _recorded_command(ctx: click.Context) -> str:
    """``s2cl lut build`` with the options given on the command line, for the LUT's provenance (however the
    command was started: the ``s2cl`` script, ``python -m s2cl`` or ``main(argv)``)."""
    words = BUILD_COMMAND.split()
    for param in ctx.command.params:
        if param.name is None or ctx.get_parameter_source(param.name) is not click.core.ParameterSource.COMMANDLINE:
            continue
        flag = max(param.opts, key=len)
        is_flag = isinstance(param, click.Option) and param.is_flag
        words += [flag] if is_flag else [flag, str(ctx.params[param.name])]
    return shlex.join(words)
