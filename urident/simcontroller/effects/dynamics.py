"""Effects of unmodelled mechanics: a payload the model does not know, finite joint stiffness."""

from __future__ import annotations

import numpy as np
from scipy import signal

from urident.simcontroller.effects.base import Effect, EffectUsageError
from urident.simcontroller.effects.params import N_JOINTS, Param


def payload_params(spec, mass_kg: float, offset_m: np.ndarray, inertia_com=None) -> np.ndarray:
    """The 78-vector of a payload of ``mass_kg`` with centre of mass ``offset_m`` in the tool
    (flange) frame and inertia ``inertia_com`` (3×3 about the centre of mass, flange axes; default
    a point mass), carried by body 6 (all other entries zero)."""
    from urident.model.parameters import body_params, tool_body_vector

    r = np.asarray(spec.tool_rotation, dtype=float)
    com = np.asarray(spec.tool_xyz) + r @ np.asarray(offset_m, float)
    inertia = np.zeros((3, 3)) if inertia_com is None else r @ np.asarray(inertia_com, float) @ r.T
    return tool_body_vector(body_params(mass_kg, com, inertia))


def inertia_matrix(diagonal, products) -> np.ndarray:
    """3×3 inertia from [Ixx, Iyy, Izz] and [Ixy, Ixz, Iyz] (URScript's order)."""
    from urident.model.parameters import inertia_matrix as from_six

    return from_six(np.concatenate([np.asarray(diagonal, float), np.asarray(products, float)]), "ur")


class PayloadError(Effect):
    name = "payload_error"
    summary = "an unmodelled payload: a rigid body at the tool adds gravity and inertial torque"
    details = ("τ = RNEA of a rigid body on link 6: mass_kg with centre of mass offset_m (tool "
               "flange frame) and inertia about it inertia_kg_m2 [Ixx, Iyy, Izz] plus "
               "inertia_products_kg_m2 [Ixy, Ixz, Iyz] (flange axes, URScript's order; default a "
               "point mass): gravity, inertial, Coriolis and centrifugal torque, applied on the "
               "listed joints (default all; normally leave it so).")
    params = (
        Param("mass_kg", "number", 0.5, "payload mass [kg]", low=0.0, high=100.0),
        Param("offset_m", "vector3", (0.0, 0.0, 0.0), "mass position in the tool frame [m]",
              low=-2.0, high=2.0),
        Param("inertia_kg_m2", "vector3", (0.0, 0.0, 0.0),
              "principal-axis entries Ixx, Iyy, Izz about the centre of mass [kg·m²]", low=0.0, high=100.0),
        Param("inertia_products_kg_m2", "vector3", (0.0, 0.0, 0.0),
              "products Ixy, Ixz, Iyz about the centre of mass [kg·m²]", low=-100.0, high=100.0),
    )
    link_side = True

    def reset(self) -> None:
        ctx = self.context
        v = self.config.values
        inertia = inertia_matrix(v["inertia_kg_m2"], v["inertia_products_kg_m2"])
        ev = np.linalg.eigvalsh(inertia)
        if ev.min() < -1e-12 or ev.sum() - 2 * ev.max() < -1e-12:
            from urident.errors import ConfigError

            raise ConfigError("payload_error: inertia_kg_m2 / inertia_products_kg_m2 are not a "
                                   "physical inertia (positive semidefinite, triangle inequality)")
        self._params = payload_params(ctx.spec, v["mass_kg"], v["offset_m"], inertia)
        self._pin = None

    def torque(self, t, q, qd, qdd, tau_model, temperatures, link_extra):
        import pinocchio as pin

        if self._pin is None:
            from urident.model.pinocchio_model import build_model

            # RNEA with the payload on body 6 minus RNEA without (a zero-mass body is not a
            # valid Pinocchio inertia, so the payload cannot stand alone)
            loaded = build_model(self.context.spec, self.context.params + self._params)
            self._pin = (loaded, loaded.createData(), *self.context.pinocchio())
        loaded, loaded_data, plain, plain_data = self._pin
        x = [np.asarray(v, dtype=float) for v in (q, qd, qdd)]
        tau = pin.rnea(loaded, loaded_data, *x) - pin.rnea(plain, plain_data, *x)
        return np.where(self.mask, tau, 0.0)

    def offline_torque(self, t, q, qd, qdd, tau_model, temperatures, link_extra):
        from urident.model import joint_torques

        tau = joint_torques(self.context.spec, self._params, q, qd, qdd, self.context.friction_eps)
        return np.where(self.mask, tau, 0.0)


def _bilinear(num, den, dt: float):
    """Bilinear (Tustin) transform, s = (2/dt)(z − 1)/(z + 1), of second-order s-domain filters
    ``(n0 s² + n1 s + n2)/(d0 s² + d1 s + d2)`` (coefficient arrays, one entry per filter):
    z-domain ``(b (m, 3), a (m, 3))`` with ``a[:, 0] == 1``."""
    g = 2.0 / dt

    def z_poly(c0, c1, c2):
        c0 = c0 * g * g
        c1 = c1 * g
        return np.stack([c0 + c1 + c2, 2.0 * (c2 - c0), c0 - c1 + c2], axis=1)

    b, a = z_poly(*num), z_poly(*den)
    return b / a[:, :1], a / a[:, :1]


class _Filters:
    """Direct-form-II-transposed second-order IIR filters, one per joint (the algorithm of
    ``scipy.signal.lfilter``, so the stepped and the whole-run forms agree to rounding)."""

    def __init__(self, b: np.ndarray, a: np.ndarray, u0: np.ndarray):
        self.b, self.a = b, a                                     # (m, 3), a[:, 0] == 1
        self.z = np.array([signal.lfilter_zi(bi, ai) for bi, ai in zip(b, a)]) * u0[:, None]

    def step(self, u: np.ndarray) -> np.ndarray:
        b, a, z = self.b, self.a, self.z
        y = b[:, 0] * u + z[:, 0]
        z0 = b[:, 1] * u - a[:, 1] * y + z[:, 1]
        z1 = b[:, 2] * u - a[:, 2] * y
        self.z = np.stack([z0, z1], axis=1)
        return y

    def run(self, u: np.ndarray) -> np.ndarray:
        """Filter ``u (N, m)`` from the steady state of ``u[0]``: ``y[0] = u[0]``."""
        y = np.empty_like(u)
        y[0] = u[0]
        for k, (bi, ai) in enumerate(zip(self.b, self.a)):
            zi = signal.lfilter_zi(bi, ai) * u[0, k]
            y[1:, k] = signal.lfilter(bi, ai, u[1:, k], zi=zi)[0]
        return y


class JointElasticity(Effect):
    name = "joint_elasticity"
    summary = "finite joint stiffness: the link lags the motor, spring torque is filtered"
    details = ("Per joint a spring k and damper d between motor (measured q) and link of inertia "
               "J: J·ë + d·ė + k·e = τ_link, deflection e = q_motor − q_link, the motor feels "
               "τ_spring = k·e + d·ė = H(s)·τ_link, H = (d·s + k)/(J·s² + d·s + k), with τ_link the "
               "model's rigid-body torque plus any payload_error torque; d = 2·ζ·√(k·J); "
               "discretised with the bilinear transform at the controller period, starting at "
               "rest (static deflection). Resonances above the Nyquist frequency are not "
               "resolved. Stateful.")
    params = (
        Param("stiffness_nm_per_rad", "joint", 20000.0, "joint stiffness k [N·m/rad]",
              low=0.0, low_inclusive=False),
        Param("damping_ratio", "joint", 0.1, "ζ of the link resonance [-]", low=0.0, high=10.0),
        Param("link_inertia_kg_m2", "joint", None,
              "link-side inertia J [kg·m²]; default: the model's mass-matrix diagonal at the "
              "first sample", low=0.0, low_inclusive=False),
    )
    stateful = True

    def reset(self) -> None:
        self._first: tuple[float, np.ndarray, np.ndarray] | None = None
        self._spring: _Filters | None = None
        self._deflection_filters: _Filters | None = None
        self.deflection = np.zeros(N_JOINTS)      # e = q_motor − q_link [rad], last step
        self._cached = None

    def _coefficients(self, dt: float, q0: np.ndarray):
        """((b, a) of the spring torque filter, (b, a) of the deflection filter), one row per
        listed joint; cached per (dt, q0)."""
        key = (float(dt), tuple(np.asarray(q0, dtype=float)))
        if self._cached is not None and self._cached[0] == key:
            return self._cached[1]
        given = self.config.values["link_inertia_kg_m2"]
        inertia = self.context.mass_matrix_diagonal(q0) if given is None else given
        idx = list(self.joints)
        k = self.value("stiffness_nm_per_rad", 1.0)[idx]
        zeta = self.value("damping_ratio")[idx]
        j_link = np.asarray(inertia, dtype=float)[idx]
        d = 2.0 * zeta * np.sqrt(k * j_link)
        zero = np.zeros_like(k)
        den = (j_link, d, k)
        result = (_bilinear((zero, d, k), den, dt), _bilinear((zero, zero, np.ones_like(k)), den, dt))
        self._cached = (key, result)
        return result

    def _load(self, tau_model, qd, qdd, link_extra):
        return self.context.link_torque(tau_model, qd, qdd) + link_extra

    def torque(self, t, q, qd, qdd, tau_model, temperatures, link_extra):
        idx = list(self.joints)
        u = self._load(tau_model, qd, qdd, link_extra)
        out = np.zeros(N_JOINTS)
        if self._first is None:
            self._first = (float(t), np.array(q, dtype=float), u.copy())
            self._static_deflection(u)
            return out
        if self._spring is None:
            t0, q0, u0 = self._first
            dt = float(t) - t0
            if not dt > 0:
                raise EffectUsageError("joint_elasticity: time must advance between samples")
            (bs, as_), (bd, ad) = self._coefficients(dt, q0)
            self._spring = _Filters(bs, as_, u0[idx])
            self._deflection_filters = _Filters(bd, ad, u0[idx])
        y = self._spring.step(u[idx])
        self.deflection = np.zeros(N_JOINTS)
        self.deflection[idx] = self._deflection_filters.step(u[idx])
        out[idx] = y - u[idx]
        return out

    def _static_deflection(self, u: np.ndarray) -> None:
        self.deflection = np.zeros(N_JOINTS)
        idx = list(self.joints)
        self.deflection[idx] = u[idx] / self.value("stiffness_nm_per_rad", 1.0)[idx]

    def offline_torque(self, t, q, qd, qdd, tau_model, temperatures, link_extra):
        out = np.zeros_like(np.asarray(q, dtype=float))
        if len(t) < 2:
            return out
        idx = list(self.joints)
        u = self._load(tau_model, qd, qdd, link_extra)[:, idx]
        (bs, as_), _ = self._coefficients(float(t[1] - t[0]), q[0])
        out[:, idx] = _Filters(bs, as_, u[0]).run(u) - u
        return out

    def offline_deflection(self, t, q, qd, qdd, tau_model, link_extra) -> np.ndarray:
        """(N, 6) deflection e = q_motor − q_link [rad] (zero on joints not listed)."""
        out = np.zeros_like(np.asarray(q, dtype=float))
        idx = list(self.joints)
        u = self._load(tau_model, qd, qdd, link_extra)[:, idx]
        k = self.value("stiffness_nm_per_rad", 1.0)[idx]
        if len(t) < 2:
            out[:, idx] = u / k
            return out
        _, (bd, ad) = self._coefficients(float(t[1] - t[0]), q[0])
        e = _Filters(bd, ad, u[0]).run(u)
        e[0] = u[0] / k
        out[:, idx] = e
        return out
