"""A payload on the tool flange: the type, its ten inertial parameters and the map to the last
body's parameters.

Frames. A payload is written in UR's tool flange frame F (the robot file's ``tool`` frame: origin
on the flange face, z out of the flange), as ``set_target_payload`` takes it: mass m, centre of
mass c (F), inertia I_c about the centre of mass with F's axes. Its torque adds to the last
body's (:data:`urident.model.parameters.TOOL_BODY`, frame K_6), so the flange-frame ten-vector
φ_F = (m, m·c, J_F about F's origin) maps linearly to K_6: with r_K6 = t + R r_F,
h_K6 = m t + R h_F and J_K6 = R J_F Rᵀ − m S(t)S(t) − S(t)S(R h_F) − S(R h_F)S(t) (S: cross-product
matrix). :func:`flange_map` is that 10×10 matrix L. Estimating a payload from logs is
:mod:`urident.ident.payload`'s.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from urident.errors import ConfigError
from urident.model.parameters import inertia_matrix, inertia_vector

#: Names of the flange-frame ten-vector φ_F (first moments m·c, inertia about the flange origin).
PAYLOAD_FIELDS = ("m", "mcx", "mcy", "mcz", "Jxx", "Jyy", "Jzz", "Jyz", "Jxz", "Jxy")

class PayloadError(ConfigError):
    """Bad payload input: a non-positive mass, no wrist motion, a payload for another robot."""


@dataclass(frozen=True)
class Payload:
    """A payload in UR's tool flange frame (module doc). ``sigma``: the same keys' standard
    deviations (NaN where fixed); ``identifiable``: names of the parameters the data determined."""

    robot: str
    mass_kg: float
    com_m: np.ndarray              # (3,) flange frame
    inertia_kg_m2: np.ndarray      # (3, 3) about the centre of mass, flange axes
    sigma: dict = field(default_factory=dict)
    identifiable: tuple[str, ...] = PAYLOAD_FIELDS
    method: str = "given"
    info: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not (np.isfinite(self.mass_kg) and self.mass_kg > 0):
            raise PayloadError(f"payload mass must be positive, not {self.mass_kg:g} kg")
        object.__setattr__(self, "com_m", np.asarray(self.com_m, dtype=float).reshape(3))
        inertia = np.asarray(self.inertia_kg_m2, dtype=float).reshape(3, 3)
        if not (np.all(np.isfinite(self.com_m)) and np.all(np.isfinite(inertia))):
            raise PayloadError(f"payload centre of mass and inertia must be finite, not {self.com_m.tolist()}, "
                               f"{inertia.tolist()}")
        object.__setattr__(self, "inertia_kg_m2", 0.5 * (inertia + inertia.T))

    @property
    def flange_vector(self) -> np.ndarray:
        """φ_F: (m, m·c, J about the flange origin as Jxx, Jyy, Jzz, Jyz, Jxz, Jxy)."""
        c = self.com_m
        j = self.inertia_kg_m2 + self.mass_kg * (c @ c * np.eye(3) - np.outer(c, c))
        return np.r_[self.mass_kg, self.mass_kg * c, j[0, 0], j[1, 1], j[2, 2], j[1, 2], j[0, 2], j[0, 1]]

    def body_params(self, spec) -> np.ndarray:
        """The payload's ten paper parameters about K_6 (add to :data:`TOOL_BODY`)."""
        return flange_map(spec) @ self.flange_vector

    def urscript(self) -> str:
        """``set_target_payload(m, [cx, cy, cz], [Ixx, Iyy, Izz, Ixy, Ixz, Iyz])``."""
        inertia = inertia_vector(self.inertia_kg_m2, "ur")
        return (f"set_target_payload({self.mass_kg:.4f}, [{', '.join(f'{v:.5f}' for v in self.com_m)}], "
                f"[{', '.join(f'{v:.6f}' for v in inertia)}])")

    def describe(self) -> str:
        c = self.com_m * 1000
        ev = np.linalg.eigvalsh(self.inertia_kg_m2)
        return (f"mass {self.mass_kg:.4f} kg, centre of mass [{c[0]:.1f}, {c[1]:.1f}, {c[2]:.1f}] mm "
                f"(flange frame), principal inertias [{', '.join(f'{v:.5f}' for v in ev)}] kg·m²")


def skew(v) -> np.ndarray:
    x, y, z = v
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def _to_body(spec, phi: np.ndarray) -> np.ndarray:
    """φ_F → the paper's ten parameters about K_6 (module doc)."""
    t = np.asarray(spec.tool_xyz, dtype=float)
    r = np.asarray(spec.tool_rotation, dtype=float)
    m, h = phi[0], r @ phi[1:4]
    jf = inertia_matrix(phi[4:10], "flange")
    st, sh = skew(t), skew(h)
    j = r @ jf @ r.T - m * st @ st - st @ sh - sh @ st
    hk = m * t + h
    return np.array([m, hk[0], hk[1], hk[2], j[0, 0], j[1, 1], j[2, 2], -j[1, 2], -j[0, 2], -j[0, 1]])


def flange_map(spec) -> np.ndarray:
    """L (10×10): the paper's K_6 parameters = L φ_F (module doc)."""
    return np.column_stack([_to_body(spec, e) for e in np.eye(10)])


def from_flange_vector(robot: str, phi: np.ndarray, **kw) -> Payload:
    phi = np.asarray(phi, dtype=float)
    m = float(phi[0])
    if not m > 0:
        raise PayloadError(f"estimated payload mass is {m:.4g} kg, not positive: the logs do not "
                           "determine a payload (is one mounted, and do the logs move the arm?)")
    c = phi[1:4] / m
    inertia = inertia_matrix(phi[4:10], "flange") - m * (c @ c * np.eye(3) - np.outer(c, c))
    return Payload(robot, m, c, inertia, **kw)
