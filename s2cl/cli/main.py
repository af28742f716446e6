"""The ``s2cl`` command line: one click group. Every command has ``--help``; errors print one line and exit 2.

The commands live by subject: :mod:`~s2cl.cli.simulate`, :mod:`~s2cl.cli.sweep` (with ``optimise``),
:mod:`~s2cl.cli.info` (scenes, libraries, devices, sensor, srf, residuals), :mod:`~s2cl.cli.scorecard`,
:mod:`~s2cl.cli.study` and
:mod:`~s2cl.cli.lut`; this module gathers them and turns errors into one line.
"""

from __future__ import annotations

import os
import signal
import sys

import click

from s2cl.cli.info import devices, libraries, residuals, scenes, sensor, srf
from s2cl.cli.lut import lut
from s2cl.cli.scorecard import scorecard
from s2cl.cli.simulate import simulate
from s2cl.cli.study import study
from s2cl.cli.sweep import optimise, sweep
from s2cl.errors import S2CLError
from s2cl.logs import LOGGER, configure


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
      s2cl scorecard             score the scene's applications on S2A, S2B, OLI, Landsat Next, ...
      s2cl scenes                list built-in scenes
      s2cl libraries             list built-in spectral libraries
      s2cl sensor                show the sensor table and its noise model
      s2cl srf B1 --plot srf.png model vs measured SRF of a band (paper Fig. 2)
      s2cl study NAME            studies: atmospheric bands (cirrus, ...), spectral stability
      s2cl residuals             band-averaging residual of the atmospheric correction
      s2cl devices               list OpenCL devices
      s2cl lut build -o FILE     rebuild the atmosphere look-up table with 6S

    Put -v before the command (`s2cl -v simulate`) to see the DEBUG log.
    """
    configure(verbose)


for _command in (simulate, optimise, sweep, scorecard, scenes, libraries, devices, sensor, srf, residuals, study, lut):
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


#: click >= 8.2 raises this for a group called without a command (8.1 prints the help and exits 0 itself)
_NO_ARGS_IS_HELP = getattr(click.exceptions, "NoArgsIsHelpError", ())


def main(argv: list[str] | None = None) -> None:
    """Entry point: run the CLI, turning s2cl errors and click's usage errors into one line and exit code 2.

    The safety nets below catch what a user's environment can still cause after every check (a disk
    filled by another process, memory taken by another process, a file removed during the run): one
    line naming the file where there is one, exit code 2, never a traceback. Ctrl-C (exit code 130) and
    SIGTERM (exit code 143) remove the temporary files of the writes under way and leave finished
    files and sweep chunks in place.
    """
    _on_sigterm()
    _tolerant_streams()
    args = sys.argv[1:] if argv is None else list(argv)
    try:
        os.getcwd()
    except OSError:
        _fail("the working folder no longer exists (it was removed or moved): cd into an existing folder and run "
              "again")
    try:
        _invoke(args)
    except click.exceptions.Abort:
        click.echo("aborted", err=True)
        sys.exit(130)
    except Terminated:
        click.echo("terminated", err=True)
        sys.exit(143)
    except _NO_ARGS_IS_HELP as err:  # `s2cl sweep` alone: its help, not an error
        click.echo(err.ctx.get_help())
    except click.UsageError as err:
        command = err.ctx.command_path if err.ctx is not None else "s2cl"
        _fail(f"{_one_line(err.format_message())} (see `{command} --help`)")
    except click.ClickException as err:
        _fail(_one_line(err.format_message()))
    except S2CLError as err:
        _fail(str(err))
    except OSError as err:
        where = f"{err.filename}: " if err.filename else ""
        _fail(f"{where}{err.strerror or type(err).__name__} (errno {err.errno})")
    except MemoryError:
        _fail("out of memory: an allocation failed although the run's estimate fitted --max-memory (another "
              "process may have taken the memory, or the estimate missed); free memory or reduce the scene "
              "(surface.copies, grid.step_nm, the library) and run again")
    except RecursionError:
        _fail("input nested too deeply")


def _invoke(args: list[str]) -> None:
    """Parse ``args`` and run the command, with click's own error printing off (:func:`main` prints one
    line); Ctrl-C becomes click's Abort without the blank line click would print first."""
    try:
        with cli.make_context("s2cl", args) as ctx:
            cli.invoke(ctx)
    except click.exceptions.Exit as done:  # --help, --version
        if done.exit_code:
            sys.exit(done.exit_code)
    except (KeyboardInterrupt, EOFError):
        raise click.exceptions.Abort() from None
    except BrokenPipeError:  # `s2cl scenes | head -1`: the reader left; as click does, exit 1 quietly
        # what is still buffered goes nowhere, so the interpreter's own flush at exit cannot fail again (the
        # recipe of Python's signal module documentation, "Note on SIGPIPE"; click's own wrapper is deprecated)
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        sys.exit(1)


def _one_line(text: str) -> str:
    """Click's messages may hold line breaks (a suggestion on its own line): join them."""
    return " ".join(part.strip() for part in text.splitlines() if part.strip())


def _tolerant_streams() -> None:
    """Never crash on a character the console cannot show (``PYTHONIOENCODING=ascii``, a C locale): stdout
    and stderr replace it with ``?``; rich then draws its tables with ASCII lines."""
    for stream in (sys.stdout, sys.stderr):
        if getattr(stream, "errors", None) == "strict" and hasattr(stream, "reconfigure"):
            try:
                stream.reconfigure(errors="replace")
            except (ValueError, OSError):  # a closed or detached stream: leave it
                pass


def _fail(message: str) -> None:
    """Print ``error: MESSAGE`` as one line (further lines, e.g. a build log, go to the DEBUG log) and exit 2."""
    first, _, rest = message.partition("\n")
    if rest:
        LOGGER.debug("%s", rest)
    click.echo(f"error: {first}" + (" (s2cl -v shows the details)" if rest else ""), err=True)
    sys.exit(2)


if __name__ == "__main__":
    main()
