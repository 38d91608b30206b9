"""The settings half of fuelid's estimator convention: scikit-learn's get_params and set_params.

Every estimator (``fuelid.identify``'s, the gray-box one, the online K tracker) keeps its
constructor's keyword settings unchanged as attributes, listed in ``_SETTINGS``;
``get_params()`` returns them, ``set_params(**kw)`` changes them (effective at the next fit) and
the ``repr`` shows them. The fitted half (attributes ending in ``_``, present only after ``fit``)
is each estimator's own.
"""

from __future__ import annotations

from typing import Any, ClassVar, Self

from fuelid.errors import FuelidError

__all__ = ["Params"]


class Params:
    """Settings by name, as scikit-learn estimators have them.

    Examples
    --------
    >>> class Lag(Params):
    ...     _SETTINGS = ("T", "order")
    ...     def __init__(self, T=1.0, order=1):
    ...         self.T, self.order = T, order
    >>> Lag(T=2.0)
    Lag(T=2.0, order=1)
    >>> Lag().set_params(order=2).get_params()
    {'T': 1.0, 'order': 2}
    """

    _SETTINGS: ClassVar[tuple[str, ...]] = ()

    def get_params(self) -> dict[str, Any]:
        """The constructor's settings by name (``type(est)(**est.get_params())`` is a copy)."""
        return {name: getattr(self, name) for name in self._SETTINGS}

    def set_params(self, **params: Any) -> Self:
        """Change settings (they take effect at the next ``fit``); returns ``self``."""
        unknown = sorted(set(params) - set(self._SETTINGS))
        if unknown:
            raise FuelidError(
                f"{type(self).__name__} has no setting {', '.join(unknown)}; its settings are "
                f"{', '.join(self._SETTINGS)}"
            )
        for name, value in params.items():
            setattr(self, name, value)
        return self

    def __repr__(self) -> str:
        args = ", ".join(f"{name}={value!r}" for name, value in self.get_params().items())
        return f"{type(self).__name__}({args})"
