"""The one ``s2cl`` logger, and how the command line shows it.

Library code logs through :data:`LOGGER` (or a child, ``logging.getLogger("s2cl.<part>")``) and never
prints. Nothing reaches the terminal unless an application asks: the CLI calls :func:`configure`
(warnings by default, DEBUG with ``-v``); a Python user calls :func:`configure` or sets up
``logging`` as usual. Compiler logs of kernel builds are DEBUG records of ``s2cl.cl.runtime``.
"""

from __future__ import annotations

import logging
import sys

LOGGER = logging.getLogger("s2cl")
LOGGER.addHandler(logging.NullHandler())  # a library stays silent until the application configures logging

_HANDLER_NAME = "s2cl-cli"


def configure(verbose: int = 0, stream=None) -> None:
    """Show s2cl's log records on ``stream`` (stderr): warnings and errors, or everything with
    ``verbose`` >= 1. Calling it again replaces the handler it installed, never stacks another."""
    level = logging.DEBUG if verbose > 0 else logging.WARNING
    for handler in [h for h in LOGGER.handlers if h.get_name() == _HANDLER_NAME]:
        LOGGER.removeHandler(handler)
    handler = logging.StreamHandler(stream or sys.stderr)
    handler.set_name(_HANDLER_NAME)
    handler.setFormatter(logging.Formatter("%(name)s %(levelname)s: %(message)s"))
    handler.setLevel(level)
    LOGGER.addHandler(handler)
    LOGGER.setLevel(level)
