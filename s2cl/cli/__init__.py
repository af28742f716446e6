"""The command line: one click group (`s2cl --help`)."""

from s2cl.cli.main import main

__all__ = ["main"]
