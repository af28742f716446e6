"""The ``s2cl`` command line: one click group. Every command has ``--help``; errors print one line and exit 2.

The commands live by subject: :mod:`~s2cl.cli.simulate`, :mod:`~s2cl.cli.sweep` (with ``optimise``),
:mod:`~s2cl.cli.info` (scenes, libraries, devices, sensor, srf, residuals), :mod:`~s2cl.cli.study` and
:mod:`~s2cl.cli.lut`; this module gathers them and turns errors into one line.
"""

from __future__ import annotations

import signal
import sys

import click

from s2cl.cli.info import devices, libraries, residuals, scenes, sensor, srf
from s2cl.cli.lut import lut
from s2cl.cli.simulate import simulate
from s2cl.cli.study import study
from s2cl.cli.sweep import optimise, sweep
from s2cl.errors import S2CLError


@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(package_name="s2cl")
@click.option("--verbose", "-v", count=True,
              help="show s2cl's DEBUG log on stderr (device and lane choice, kernel build logs)")
def cli(verbose: int) -> None:
    """s2cl: end-to-end optical sensor simulation for spectral band selection.

    \b
    Start here:
      s2cl optimise              sweep the default scene's band designs, rank them, plot
      s2cl simulate              run the built-in default scene, write NetCDF + summary
      s2cl scenes                list built-in scenes
      s2cl libraries             list built-in spectral libraries
      s2cl sensor                show the sensor table and its noise model
      s2cl srf B1 --plot srf.png model vs measured SRF of a band (paper Fig. 2)
      s2cl study NAME            the paper's atmospheric-band studies (cirrus, water-vapour, ...)
      s2cl residuals             band-averaging residual of the atmospheric correction
      s2cl devices               list OpenCL devices
      s2cl lut build -o FILE     rebuild the atmosphere look-up table with 6S

    Put -v before the command (`s2cl -v simulate`) to see the DEBUG log.
    """
    from s2cl.logs import configure

    configure(verbose)


for _command in (simulate, optimise, sweep, scenes, libraries, devices, sensor, srf, residuals, study, lut):
    cli.add_command(_command)


class Terminated(BaseException):
    """SIGTERM arrived: raised in the main thread, so that every ``finally`` and :func:`s2cl.io.output.atomic_path`
    cleanup runs as for Ctrl-C (a BaseException: no ``except Exception`` swallows it)."""


def _terminate(signum: int, frame: object) -> None:
    raise Terminated()


def _on_sigterm() -> None:
    """Turn SIGTERM into :class:`Terminated` (only where Python owns the main thread's signals)."""
    try:
        if signal.getsignal(signal.SIGTERM) in (signal.SIG_DFL, None):
            signal.signal(signal.SIGTERM, _terminate)
    except ValueError:  # not the main thread (an embedding application): leave its handlers alone
        pass


def main(argv: list[str] | None = None) -> None:
    """Entry point: run the CLI, turning s2cl errors into one line and exit code 2.

    The safety nets below catch what a user's environment can still cause after every check (a disk
    filled by another process, memory taken by another process, a file removed during the run): one
    line naming the file where there is one, exit code 2, never a traceback. Ctrl-C (exit code 130) and
    SIGTERM (exit code 143) remove the temporary files of the writes under way and leave finished
    files and sweep chunks in place.
    """
    _on_sigterm()
    try:
        cli.main(args=argv, prog_name="s2cl", standalone_mode=False)
    except click.exceptions.Abort:
        click.echo("aborted", err=True)
        sys.exit(130)
    except Terminated:
        click.echo("terminated", err=True)
        sys.exit(143)
    except click.ClickException as err:
        err.show()
        sys.exit(err.exit_code)
    except S2CLError as err:
        _fail(str(err))
    except OSError as err:
        where = f"{err.filename}: " if err.filename else ""
        _fail(f"{where}{err.strerror or type(err).__name__} (errno {err.errno})")
    except MemoryError:
        _fail("out of memory: another process took the memory this run was estimated to need; lower --max-memory "
              "or free memory and run again")
    except RecursionError:
        _fail("input nested too deeply")


def _fail(message: str) -> None:
    """Print ``error: MESSAGE`` as one line (further lines, e.g. a build log, go to the DEBUG log) and exit 2."""
    from s2cl.logs import LOGGER

    first, _, rest = message.partition("\n")
    if rest:
        LOGGER.debug("%s", rest)
    click.echo(f"error: {first}" + (" (s2cl -v shows the details)" if rest else ""), err=True)
    sys.exit(2)


if __name__ == "__main__":
    main()
