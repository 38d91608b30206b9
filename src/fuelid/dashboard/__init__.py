"""The control-room dashboard (``fuelid dashboard``): FastAPI pages over the loops' stores."""
