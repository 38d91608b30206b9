"""Data shipped with fuelid: the reference plant configuration.

The public API
--------------
The file ``reference_plant.toml``, read with :func:`fuelid.plant.load_plant_config` (no path: the
reference plant) or ``importlib.resources.files("fuelid.data")``. No names (``__all__`` is
empty).
"""

__all__: list[str] = []
