"""Friction effects the paper's model (viscous + Coulomb) does not have: Stribeck/static
friction, load-dependent friction, temperature drift, position-dependent ripple, friction growing
faster than linearly with speed, friction driven by a neighbour's load, a Coulomb level that differs
by direction."""

from __future__ import annotations

import numpy as np

from urident.errors import ConfigError
from urident.simcontroller.effects.base import Effect
from urident.simcontroller.effects.params import Param


class Stribeck(Effect):
    name = "stribeck"
    summary = "static (Stribeck) friction: extra friction near zero velocity"
    details = ("τ = (f_s − f_c)·exp(−(q̇/v_s)²)·tanh(q̇/ε), with f_c the model's Coulomb friction; "
               "f_s from static_friction_nm, else static_friction_ratio·f_c.")
    params = (
        Param("static_friction_nm", "joint", None,
              "static (breakaway) friction f_s [N·m]; overrides static_friction_ratio", low=0.0),
        Param("static_friction_ratio", "joint", 1.3,
              "f_s / f_c, used when static_friction_nm is not given", low=0.0),
        Param("stribeck_velocity_rad_s", "joint", 0.02, "Stribeck velocity v_s [rad/s]",
              low=0.0, low_inclusive=False),
    )

    @classmethod
    def check_entry(cls, values, given, where):
        if "static_friction_nm" in given and "static_friction_ratio" in given:
            raise ConfigError(f"{where}: give static_friction_nm or static_friction_ratio, not both")

    def reset(self) -> None:
        ctx = self.context
        fs = self.config.values["static_friction_nm"]
        if fs is not None:
            delta = np.where(self.mask, fs, 0.0) - ctx.coulomb
        else:
            delta = (self.value("static_friction_ratio", 1.0) - 1.0) * ctx.coulomb
        self._delta = np.where(self.mask, delta, 0.0)
        self._vs = self.value("stribeck_velocity_rad_s", 1.0)

    def _stateless_torque(self, t, q, qd, qdd, tau_model, temperatures, link_extra):
        return self._delta * np.exp(-((qd / self._vs) ** 2)) * self.context.sign(qd)


class LoadFriction(Effect):
    name = "load_friction"
    summary = "load-dependent friction: friction proportional to the torque the gear carries"
    details = ("τ = μ·|τ_link|·tanh(q̇/ε), τ_link = the model's rigid-body torque plus any "
               "payload_error torque (the load on the gear).")
    params = (
        Param("coefficient", "joint", 0.02, "μ, friction per N·m of load [-]", low=0.0, high=1.0),
    )

    def reset(self) -> None:
        self._mu = self.value("coefficient")

    def _stateless_torque(self, t, q, qd, qdd, tau_model, temperatures, link_extra):
        ctx = self.context
        load = ctx.link_torque(tau_model, qd, qdd) + link_extra
        return self._mu * np.abs(load) * ctx.sign(qd)


class ThermalDrift(Effect):
    name = "thermal_drift"
    summary = "temperature-dependent friction: viscous/Coulomb friction drift as the joints warm up"
    details = ("ΔT = (T − T_ref) + warmup_c·(1 − exp(−(t − t₀)/warmup_time_constant_s)), T the "
               "reported joint temperature, T_ref = reference_temperature_c or T at the first "
               "sample, the second term the gearbox grease warming beyond what the joint sensor "
               "shows; τ = max(c_v·ΔT, −1)·r_v·q̇ + max(c_c·ΔT, −1)·r_c·tanh(q̇/ε) with the model's "
               "r_v, r_c. Stateful: t₀ and T_ref are taken at the first sample.")
    params = (
        Param("viscous_change_per_c", "joint", -0.01,
              "c_v, relative change of viscous friction per °C [1/°C]", low=-1.0, high=1.0),
        Param("coulomb_change_per_c", "joint", -0.003,
              "c_c, relative change of Coulomb friction per °C [1/°C]", low=-1.0, high=1.0),
        Param("warmup_c", "joint", 10.0, "grease temperature rise over the run [°C]",
              low=-100.0, high=100.0),
        Param("warmup_time_constant_s", "joint", 300.0, "time constant of the warm-up [s]",
              low=0.0, low_inclusive=False),
        Param("reference_temperature_c", "joint", None,
              "temperature at which the model's friction holds [°C]; default: the first sample's",
              low=-50.0, high=200.0),
    )
    stateful = True

    def reset(self) -> None:
        self._t0: float | None = None
        self._t_ref: np.ndarray | None = None
        self._cv = self.value("viscous_change_per_c")
        self._cc = self.value("coulomb_change_per_c")
        self._warm = self.value("warmup_c")
        self._tau = self.value("warmup_time_constant_s", 1.0)

    def _reference(self, first_temperatures: np.ndarray) -> np.ndarray:
        given = self.config.values["reference_temperature_c"]
        first = np.asarray(first_temperatures, dtype=float)
        return first.copy() if given is None else np.where(self.mask, given, first)

    def _drift(self, elapsed, qd, temperatures, t_ref):
        ctx = self.context
        d_temp = (temperatures - t_ref) + self._warm * -np.expm1(-elapsed / self._tau)
        scale_v = np.maximum(self._cv * d_temp, -1.0)
        scale_c = np.maximum(self._cc * d_temp, -1.0)
        out = scale_v * ctx.viscous * qd + scale_c * ctx.coulomb * ctx.sign(qd)
        return np.where(self.mask, out, 0.0)

    def torque(self, t, q, qd, qdd, tau_model, temperatures, link_extra):
        if self._t0 is None:
            self._t0 = float(t)
            self._t_ref = self._reference(temperatures)
        return self._drift(float(t) - self._t0, qd, temperatures, self._t_ref)

    def offline_torque(self, t, q, qd, qdd, tau_model, temperatures, link_extra):
        t_ref = self._reference(temperatures[0])
        return self._drift((t - t[0])[:, None], qd, temperatures, t_ref)


class PositionRipple(Effect):
    name = "position_ripple"
    summary = "position-dependent torque ripple or friction at a gear harmonic"
    details = ("τ = A·sin(k·q + φ) (mode torque: cogging / gear ripple) or A·sin(k·q + φ)·"
               "tanh(q̇/ε) (mode friction: position-dependent friction); k = 101 is the motor's "
               "once-per-revolution harmonic of a 101:1 gear, a low k (1–4) a flexspline harmonic.")
    params = (
        Param("amplitude_nm", "joint", 0.5, "ripple amplitude A [N·m]", low=0.0),
        Param("harmonic", "joint", 101.0, "k, periods per joint revolution [-]",
              low=0.0, low_inclusive=False, high=10000.0),
        Param("phase_rad", "joint", 0.0, "phase φ [rad]", low=-100.0, high=100.0),
        Param("mode", "choice", "torque", "torque: conservative ripple; friction: × sign(q̇)",
              choices=("torque", "friction")),
    )

    def reset(self) -> None:
        self._amp = self.value("amplitude_nm")
        self._k = self.value("harmonic")
        self._phase = self.value("phase_rad")
        self._friction = self.config.values["mode"] == "friction"

    def _stateless_torque(self, t, q, qd, qdd, tau_model, temperatures, link_extra):
        out = self._amp * np.sin(self._k * q + self._phase)
        if self._friction:
            out = out * self.context.sign(qd)
        return out


class QuadraticViscous(Effect):
    name = "quadratic_viscous"
    summary = "friction growing faster than linearly with speed (lubricant drag): c₂·q̇·|q̇|"
    details = ("τ = c₂·q̇·|q̇|: at high speed the gear's lubricant drag rises above the linear "
               "viscous law of the model.")
    params = (
        Param("coefficient_nm_s2", "joint", 2.0, "c₂ [N·m·s²/rad²]", low=0.0),
    )

    def reset(self) -> None:
        self._c2 = self.value("coefficient_nm_s2")

    def _stateless_torque(self, t, q, qd, qdd, tau_model, temperatures, link_extra):
        return self._c2 * qd * np.abs(qd)


class NeighbourLoadFriction(Effect):
    name = "neighbour_load_friction"
    summary = "bearing friction driven by a neighbour's load: μ·|τ_link,k|·tanh(q̇/ε)"
    details = ("τ_j = μ·|τ_link,k|·tanh(q̇_j/ε), k the neighbour joint whose link moment the joint's "
               "bearing carries (default the next joint, the last joint's previous one).")
    params = (
        Param("coefficient", "joint", 0.02, "μ, friction per N·m of the neighbour's load [-]", low=0.0, high=1.0),
        Param("neighbour", "joint", None, "the neighbour joint k (1-based); default the next joint",
              low=1.0, high=6.0),
    )

    def reset(self) -> None:
        self._mu = self.value("coefficient")
        given = self.config.values["neighbour"]
        default = np.r_[np.arange(1, 6), 4]                   # the next joint, the last: the previous
        k = default if given is None else np.where(self.mask, np.asarray(given, float) - 1, default)
        self._k = np.asarray(np.round(k), int)

    def _stateless_torque(self, t, q, qd, qdd, tau_model, temperatures, link_extra):
        ctx = self.context
        load = ctx.link_torque(tau_model, qd, qdd) + link_extra
        return self._mu * np.abs(load[..., self._k]) * ctx.sign(qd)


class AsymmetricCoulomb(Effect):
    name = "asymmetric_coulomb"
    summary = "Coulomb friction that differs by direction: (ΔF/2)·|tanh(q̇/ε)|"
    details = ("The Coulomb level is f_c + ΔF/2 moving forwards and f_c − ΔF/2 backwards (f_c the "
               "model's): τ = (ΔF/2)·|tanh(q̇/ε)|, an offset independent of the direction that acts "
               "only while the joint moves (seals and preloads are direction-dependent).")
    params = (
        Param("coulomb_difference_nm", "joint", 0.5,
              "ΔF, the forward minus the backward Coulomb level [N·m]", low=-1000.0, high=1000.0),
    )

    def reset(self) -> None:
        self._half = 0.5 * self.value("coulomb_difference_nm")

    def _stateless_torque(self, t, q, qd, qdd, tau_model, temperatures, link_extra):
        return self._half * np.abs(self.context.sign(qd))
