""":class:`EffectSet`: the effects of one file bound to a robot, composed into the two Plant
hooks and their whole-run (offline) forms; :func:`load_effects`."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from urident.model.parameters import check_standard
from urident.model.regressor import DEFAULT_FRICTION_EPS
from urident.simcontroller.effects.base import EffectContext, EffectUsageError
from urident.simcontroller.effects.catalogue import APPLY_ORDER, EFFECTS
from urident.simcontroller.effects.config import EffectsConfig, parse_effects
from urident.simcontroller.effects.params import N_JOINTS



class _Clock:
    """Checks that a stateful hook is stepped once per period at a constant period."""

    def __init__(self, hook: str):
        self.hook = hook
        self.reset()

    def reset(self) -> None:
        self.t: float | None = None
        self.dt: float | None = None

    def tick(self, t: float, names: str) -> None:
        t = float(t)
        if self.t is not None:
            step = t - self.t
            if not step > 0:
                raise EffectUsageError(
                    f"{self.hook} called at t={t:.6f} s after t={self.t:.6f} s: the stateful "
                    f"effects ({names}) step once per controller period; call reset() to restart")
            if self.dt is None:
                self.dt = step
            elif abs(step - self.dt) > 1e-6 * self.dt:
                raise EffectUsageError(
                    f"{self.hook} stepped by {step:.6g} s after {self.dt:.6g} s: the stateful "
                    f"effects ({names}) need a constant controller period")
        self.t = t


class EffectSet:
    """The effects of one effects file, bound to a robot (``spec``, the torque model's 78-vector
    ``params``, default the robot file's, and ``friction_eps``).

    Plant hooks (one call each per controller period, stateful effects step on every call):
    ``extra_torque(t, q, qd, qdd, tau_model, temperatures) -> (6,)`` and
    ``measure_current(t, current, q, qd, temperatures) -> (6,)``. Whole-run forms on sample-major
    arrays (pure; they neither use nor change the hooks' state): :meth:`offline_extra_torque`,
    :meth:`offline_measure_current`. An empty set adds nothing.
    """

    def __init__(self, config: EffectsConfig, spec=None, params=None,
                 friction_eps: float = DEFAULT_FRICTION_EPS, rng: np.random.Generator | None = None):
        self.config = config
        self.spec = spec
        self.rng = rng  # no effect draws random numbers today; kept for determinism by seed
        self.friction_eps = float(friction_eps)
        order = {name: k for k, name in enumerate(APPLY_ORDER)}
        self._entries = sorted(config.entries, key=lambda e: (order[e.name], e.index))
        self.context: EffectContext | None = None
        if spec is not None:
            p = spec.nominal_params if params is None else check_standard(params)
            self.context = EffectContext(spec, p.copy(), self.friction_eps)
        self._torque_effects: list | None = None
        self._current_effects: list | None = None
        self._torque_clock = _Clock("extra_torque")
        self._current_clock = _Clock("measure_current")
        if self.context is not None or not any(EFFECTS[e.name].needs_robot for e in self._entries):
            self._build()

    # ------------------------------------------------------------------ construction
    def _build(self) -> None:
        effects = [EFFECTS[e.name](e, self.context) for e in self._entries]
        self._torque_effects = [e for e in effects if e.hook == "torque"]
        self._current_effects = [e for e in effects if e.hook == "current"]

    def bind(self, spec, params=None, friction_eps: float | None = None) -> "EffectSet":
        """A fresh set of the same effects bound to ``spec`` (and ``params``)."""
        eps = self.friction_eps if friction_eps is None else friction_eps
        return EffectSet(self.config, spec, params, eps, self.rng)

    def _effects(self, hook: str) -> list:
        if self._torque_effects is None:
            raise EffectUsageError(
                f"effects {', '.join(self.names)} need the robot: pass spec= to load_effects() "
                "or use EffectSet.bind(spec)")
        return self._torque_effects if hook == "torque" else self._current_effects

    def reset(self) -> None:
        """Forget the state of every stateful effect (start a new run)."""
        for clock in (self._torque_clock, self._current_clock):
            clock.reset()
        for effect in (self._torque_effects or []) + (self._current_effects or []):
            effect.reset()

    # ------------------------------------------------------------------ description
    @property
    def names(self) -> tuple[str, ...]:
        """Catalogue names of the effects present (catalogue order, each once)."""
        return self.config.names

    @property
    def entries(self):
        """The validated file entries, in the order they are applied."""
        return tuple(self._entries)

    @property
    def stateful(self) -> bool:
        return any(EFFECTS[e.name].stateful for e in self._entries)

    def __len__(self) -> int:
        return len(self._entries)

    def joints_of(self, name: str) -> tuple[int, ...]:
        """1-based joints on which effect ``name`` acts (empty when absent)."""
        return tuple(sorted(j + 1 for e in self._entries if e.name == name for j in e.joints))

    def as_dict(self) -> dict[str, Any]:
        """Every entry with all parameters explicit: the ground truth of a simulation."""
        return self.config.as_dict()

    def describe(self) -> str:
        """One line per entry: name, joints and parameters; 'no effects' when empty."""
        if not self._entries:
            return f"{self.config.source}: no effects"
        lines = [f"{self.config.source}: {len(self._entries)} effect(s)"]
        for e in self._entries:
            d = e.as_dict()
            joints = ",".join(str(j) for j in d.pop("joints"))
            d.pop("name")
            params = ", ".join(f"{k}={_short(v)}" for k, v in d.items())
            lines.append(f"  {e.name} on joints {joints}: {params}")
        return "\n".join(lines)

    def __repr__(self) -> str:
        return f"<EffectSet {self.config.source}: {', '.join(self.names) or 'no effects'}>"

    # ------------------------------------------------------------------ Plant hooks
    def extra_torque(self, t, q, qd, qdd, tau_model, temperatures) -> np.ndarray:
        """Extra joint torque [N·m] at one controller period (Plant hook)."""
        effects = self._effects("torque")
        total = np.zeros(N_JOINTS)
        if not effects:
            return total
        if any(e.stateful for e in effects):
            self._torque_clock.tick(t, _stateful_names(effects))
        args = [np.asarray(x, dtype=float) for x in (q, qd, qdd, tau_model, temperatures)]
        link_extra = np.zeros(N_JOINTS)
        for effect in effects:
            tau = effect.torque(t, *args, link_extra)
            if effect.link_side:
                link_extra = link_extra + tau
            total = total + tau
        return total

    def measure_current(self, t, current, q, qd, temperatures) -> np.ndarray:
        """Reported current [A] given the drive's current plus noise (Plant hook)."""
        effects = self._effects("current")
        out = np.array(current, dtype=float)
        if not effects:
            return out
        if any(e.stateful for e in effects):
            self._current_clock.tick(t, _stateful_names(effects))
        q, qd, temperatures = (np.asarray(x, dtype=float) for x in (q, qd, temperatures))
        for effect in effects:
            out = effect.current(t, out, q, qd, temperatures)
        return out

    # ------------------------------------------------------------------ whole-run forms
    def offline_extra_torque(self, t, q, qd, qdd, tau_model, temperatures) -> np.ndarray:
        """(N, 6) extra torque for a whole run sampled at ``t (N,)`` (constant period when a
        stateful effect is present), as the hook would give stepped from ``t[0]``."""
        effects = self._effects("torque")
        t, arrays = _check_run(t, q, qd, qdd, tau_model, temperatures, stateful=self.stateful)
        total = np.zeros((t.shape[0], N_JOINTS))
        link_extra = np.zeros_like(total)
        for effect in effects:
            tau = effect.offline_torque(t, *arrays, link_extra)
            if effect.link_side:
                link_extra = link_extra + tau
            total = total + tau
        return total

    def offline_measure_current(self, t, current, q, qd, temperatures) -> np.ndarray:
        """(N, 6) reported current for a whole run (see :meth:`measure_current`)."""
        effects = self._effects("current")
        t, (current, q, qd, temperatures) = _check_run(t, current, q, qd, temperatures,
                                                       stateful=False)
        out = current.copy()
        for effect in effects:
            out = effect.offline_current(t, out, q, qd, temperatures)
        return out

    def offline_deflection(self, t, q, qd, qdd, tau_model) -> np.ndarray:
        """(N, 6) joint deflection e = q_motor − q_link [rad] of ``joint_elasticity`` (zeros
        without it); the link position is ``q − e``."""
        effects = self._effects("torque")
        t, (q, qd, qdd, tau_model) = _check_run(t, q, qd, qdd, tau_model, stateful=True)
        out = np.zeros_like(q)
        link_extra = np.zeros_like(q)
        for effect in effects:
            if effect.link_side:
                link_extra = link_extra + effect.offline_torque(t, q, qd, qdd, tau_model, None,
                                                                np.zeros_like(q))
            if effect.name == "joint_elasticity":
                out = out + effect.offline_deflection(t, q, qd, qdd, tau_model, link_extra)
        return out


def load_effects(source: str | Path | EffectsConfig | None = None, spec=None,
                 rng: np.random.Generator | None = None, params=None,
                 friction_eps: float = DEFAULT_FRICTION_EPS) -> EffectSet:
    """Load an effects file or preset (``realistic``) into an :class:`EffectSet` bound to
    ``spec``; ``None`` gives the empty set. Any defect of the file is a one-line ConfigError."""
    if source is None:
        from urident.simcontroller.effects.config import parse_effects_text

        config = parse_effects_text("effects: []\n", "none", source="none")
    elif isinstance(source, EffectsConfig):
        config = source
    else:
        config = parse_effects(source)
    return EffectSet(config, spec=spec, params=params, friction_eps=friction_eps, rng=rng)


def _stateful_names(effects) -> str:
    return ", ".join(sorted({e.name for e in effects if e.stateful}))


def _check_run(t, *arrays, stateful: bool):
    t = np.asarray(t, dtype=float).reshape(-1)
    n = t.shape[0]
    out = []
    for a in arrays:
        a = np.asarray(a, dtype=float)
        if a.shape != (n, N_JOINTS):
            raise ValueError(f"expected ({n}, {N_JOINTS}) arrays for t of {n} samples, got {a.shape}")
        out.append(a)
    if n > 1:
        dt = np.diff(t)
        if np.any(dt <= 0):
            raise ValueError("t must increase")
        if stateful and np.max(np.abs(dt - dt[0])) > 1e-6 * dt[0]:
            raise ValueError("stateful effects need samples at a constant period")
    return t, out


def _short(value: Any) -> str:
    if isinstance(value, list):
        if len(set(value)) == 1 and len(value) > 1:
            return _short(value[0])
        return "[" + ", ".join(_short(v) for v in value) + "]"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)
