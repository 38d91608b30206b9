"""Data shipped with fuelid: the reference plant configuration."""
