"""The :class:`Effect` base class, the robot context effects are bound to, and usage errors.

An effect acts through one of the two :class:`~urident.simcontroller.plant.Plant` hooks:

* ``hook = "torque"``: ``torque(t, q, qd, qdd, tau_model, temperatures, link_extra) -> (6,)``
  joint torque [N·m] added to the model torque; ``offline_torque`` is the same on ``(N, 6)``
  arrays (``t (N,)``) for a whole run.
* ``hook = "current"``: ``current(t, current, q, qd, temperatures) -> (6,)`` the reported current
  [A] given the current the drive measures; ``offline_current`` on ``(N, 6)`` arrays.

``link_extra`` is the sum of the link-side torques of effects applied before (the payload): the
load the gear and the joint spring carry beyond the model's. Stateless effects share one
broadcasting implementation for both forms; stateful ones (``stateful = True``) keep their state
between calls, are stepped once per call, and restart with :meth:`Effect.reset`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from urident.model.parameters import COULOMB, ROTOR, VISCOUS
from urident.simcontroller.effects.params import N_JOINTS, Param


class EffectUsageError(RuntimeError):
    """An effect set is used the wrong way (a programming error, not a bad file): hooks called
    twice for one period, time going back or stepping irregularly, no robot bound."""


@dataclass(frozen=True, eq=False)
class EffectContext:
    """What the effects know about the robot: its spec, the 78-vector the plant's torque model
    uses and the friction sign smoothing ε of ``tanh(q̇/ε)``."""

    spec: Any
    params: np.ndarray
    friction_eps: float
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def rotor(self) -> np.ndarray:
        return self.params[ROTOR]

    @property
    def viscous(self) -> np.ndarray:
        return self.params[VISCOUS]

    @property
    def coulomb(self) -> np.ndarray:
        return self.params[COULOMB]

    def sign(self, qd: np.ndarray) -> np.ndarray:
        """The model's smooth sign(q̇) = tanh(q̇/ε)."""
        return np.tanh(qd / self.friction_eps)

    def link_torque(self, tau_model: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        """The model's link-side (rigid-body) torque: ``τ_model − i_G²C_M q̈ − friction(q̇)``."""
        return tau_model - self.rotor * qdd - self.viscous * qd - self.coulomb * self.sign(qd)

    def pinocchio(self):
        """(model, data) of the rigid-body model with this context's parameters (cached)."""
        if "pin" not in self._cache:
            from urident.model.pinocchio_model import build_model

            model = build_model(self.spec, self.params)
            self._cache["pin"] = (model, model.createData())
        return self._cache["pin"]

    def mass_matrix_diagonal(self, q: np.ndarray) -> np.ndarray:
        """Diagonal of the rigid-body joint-space inertia matrix at ``q`` [kg·m²]."""
        import pinocchio as pin

        model, data = self.pinocchio()
        m = pin.crba(model, data, np.asarray(q, dtype=float))
        return np.diag(m).copy()


class Effect:
    """One entry of an effects file bound to a robot (see the module docstring)."""

    name: ClassVar[str]
    summary: ClassVar[str]  # one line for the catalogue
    details: ClassVar[str] = ""  # the model, for the README / describe
    params: ClassVar[tuple[Param, ...]] = ()
    hook: ClassVar[str] = "torque"
    stateful: ClassVar[bool] = False
    link_side: ClassVar[bool] = False
    needs_robot: ClassVar[bool] = True

    def __init__(self, config, context: EffectContext | None):
        self.config = config
        self.context = context
        self.joints: tuple[int, ...] = tuple(config.joints)
        self.mask = np.zeros(N_JOINTS, dtype=bool)
        self.mask[list(self.joints)] = True
        self.reset()

    # ------------------------------------------------------------------ helpers
    def value(self, key: str, fill: float = 0.0) -> Any:
        """A parsed parameter; per-joint arrays get ``fill`` on the joints not listed."""
        v = self.config.values[key]
        if isinstance(v, np.ndarray) and v.shape == (N_JOINTS,):
            return np.where(self.mask, v, fill)
        return v

    @classmethod
    def check_entry(cls, values: dict[str, Any], given: set[str], where: str) -> None:
        """Cross-parameter checks of one file entry (raise ConfigError naming ``where``)."""

    def reset(self) -> None:
        """Forget all state (stateful effects)."""

    # ------------------------------------------------------------------ torque hook
    def torque(self, t, q, qd, qdd, tau_model, temperatures, link_extra) -> np.ndarray:
        return self._stateless_torque(t, q, qd, qdd, tau_model, temperatures, link_extra)

    def offline_torque(self, t, q, qd, qdd, tau_model, temperatures, link_extra) -> np.ndarray:
        return self._stateless_torque(t[:, None], q, qd, qdd, tau_model, temperatures, link_extra)

    def _stateless_torque(self, t, q, qd, qdd, tau_model, temperatures, link_extra) -> np.ndarray:
        raise NotImplementedError

    # ------------------------------------------------------------------ current hook
    def current(self, t, current, q, qd, temperatures) -> np.ndarray:
        return self._stateless_current(t, current, q, qd, temperatures)

    def offline_current(self, t, current, q, qd, temperatures) -> np.ndarray:
        return self._stateless_current(t[:, None], current, q, qd, temperatures)

    def _stateless_current(self, t, current, q, qd, temperatures) -> np.ndarray:
        raise NotImplementedError

    def __repr__(self) -> str:
        joints = ", ".join(str(j + 1) for j in self.joints)
        return f"<{type(self).__name__} {self.name} joints [{joints}]>"
