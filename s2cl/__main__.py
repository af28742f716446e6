"""``python -m s2cl`` runs the command line (same as the ``s2cl`` script)."""

from s2cl.cli.main import main

main()
