"""Extra global parameters fitted jointly with θ by ``estimate``: floated effects
(``estimate(effects=[...])``, columns from ``boresight.core.effect_model``) or a caller's hook
(``extra_columns=``), each scaled by a typical size so the joint system compares like with like.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
from astropy import units as u

from boresight.errors import InputTypeError, InputValueError

__all__ = ["ExtraParameters"]


class ExtraParameters:
    """Extra global parameters (floated effects or a user hook), scaled by a typical size.

    ``K`` the number of extra unknowns (0: none); ``labels``, ``units``, ``scales`` per unknown;
    ``status`` {effect: "ok" | why it was not fitted}; ``hook(obs, theta_rad, params)`` their columns.
    """

    K: int
    hook: Callable[..., Any] | None
    scales: np.ndarray

    def __init__(self, obs: Any, names: list[str] | None, hook: Callable[..., Any] | None) -> None:
        if names is not None and not (isinstance(names, (list, tuple)) and all(isinstance(n, str) for n in names)):
            raise InputTypeError.expected(
                "estimate", "effects", "effect names (a list of str, or one comma-separated str)", names
            )
        self.names: list[str] = list(names or [])
        cols: Any
        if hook is not None and self.names:
            raise InputValueError("estimate: give effects=[...] or extra_columns=..., not both")
        self.status: dict[str, str] = {}
        if self.names:
            from boresight.core import effect_model

            self._em = effect_model
            cols = effect_model.effect_columns(obs, np.zeros((obs.runs, 3)), self.names)  # unknown name → error
            self.status = dict(cols.status)
            # DECISION: an effect this data cannot evaluate (e.g. "needs velocity") is not fitted;
            # it is reported in the warnings and ``Estimate.effect_status``, never silently zero.
            self.names = [nm for nm in self.names if cols.status.get(nm) == "ok"]
            self._n = {nm: cols.slices[nm].stop - cols.slices[nm].start for nm in self.names}
            self.hook = self._effect_hook
            cols = effect_model.effect_columns(obs, np.zeros((obs.runs, 3)), self.names) if self.names else None
        else:
            self.hook = hook
            cols = hook(obs, np.zeros((obs.runs, 3)), None) if hook is not None else None
        if cols is None:
            self.K = 0
            self.labels: tuple[str, ...] = ()
            self.units: tuple[Any, ...] = ()
            self.scales = np.zeros(0)
            return
        jac = np.asarray(cols.jacobian, float)
        self.K = jac.shape[-1]
        self.labels = tuple(str(v) for v in getattr(cols, "labels", [f"p{k}" for k in range(self.K)]))
        self.units = tuple(getattr(cols, "units", [u.one] * self.K))
        self.scales = np.asarray(getattr(cols, "scales", np.ones(self.K)), float).reshape(self.K)
        if not np.all(np.isfinite(self.scales) & (self.scales > 0)):
            raise InputValueError(f"estimate: extra column scales must be finite and > 0, got {self.scales!r}")
        self.status.update(getattr(cols, "status", {}) or {})

    def _effect_hook(self, obs: Any, theta: np.ndarray, params: np.ndarray | None) -> Any:
        d: dict[str, np.ndarray] | None = None
        if params is not None:
            d, k = {}, 0
            for name in self.names:
                d[name] = params[:, k : k + self._n[name]]
                k += self._n[name]
        return self._em.effect_columns(obs, theta, self.names, d)

    def groups(self) -> Iterator[tuple[str, slice]]:
        """(name, slice of the extra unknowns) per effect, or per column for a hook."""
        if self.names:
            k = 0
            for name in self.names:
                yield name, slice(k, k + self._n[name])
                k += self._n[name]
        else:
            for k, lab in enumerate(self.labels):
                yield lab, slice(k, k + 1)
