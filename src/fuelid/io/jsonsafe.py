"""One JSON form for every result fuelid writes: NaN and ±inf as null, numpy values plain.

JSON has no NaN: a number that is not there (an undetermined second lag, a window with no setpoint
step) is written as ``null``. Every ``to_json`` and every file or store row goes through
:func:`json_ready`, so the rule is the same in the CLI's ``--json``, the HTML report's JSON and the
online store.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from typing import Any

__all__ = ["json_ready"]


def json_ready(value: Any) -> Any:
    """``value`` as plain JSON data: NaN and ±inf become None, numpy values plain numbers.

    Parameters
    ----------
    value : Any
        None, bool, str, a number, a mapping (keys become str) or a list/tuple of these, or a
        numpy scalar or array.

    Returns
    -------
    Any
        The same data, for ``json.dumps(..., allow_nan=False)``.

    Raises
    ------
    TypeError
        A value that has no JSON form (an object, a complex number).

    Examples
    --------
    >>> json_ready({"K": float("nan"), "T": [1.5, float("inf")], 3: (True, None)})
    {'K': None, 'T': [1.5, None], '3': [True, None]}
    >>> import numpy as np
    >>> json_ready({"n": np.int64(3), "ok": np.bool_(True), "x": np.array([0.5, np.nan])})
    {'n': 3, 'ok': True, 'x': [0.5, None]}
    """
    if value is None or isinstance(value, str | bool):
        return value
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Real):
        x = float(value)
        return x if math.isfinite(x) else None
    if isinstance(value, Mapping):
        return {
            (key if isinstance(key, str) else str(key)): json_ready(item)
            for key, item in value.items()
        }
    if isinstance(value, list | tuple):
        return [json_ready(item) for item in value]
    tolist = getattr(value, "tolist", None)  # numpy arrays and scalars (np.bool_ included)
    if callable(tolist):
        plain = tolist()
        if plain is not value:
            return json_ready(plain)
    raise TypeError(f"a {type(value).__name__} has no JSON form: {value!r}")
