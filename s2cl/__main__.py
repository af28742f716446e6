"""``python -m s2cl`` runs the command line (same as the ``s2cl`` script)."""

from .cli import main

main()
