"""``python -m fuelid`` runs the command line."""

from fuelid.cli import run

run()
