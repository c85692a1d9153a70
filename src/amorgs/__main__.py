"""``python -m amorgs`` — the same command line as the ``amorgs`` console script."""

from amorgs.cli import main

main()
