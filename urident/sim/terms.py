"""Which identified terms a simulator format can express, and what share of a torque the others carry.

MJCF keeps the rigid body (inertials), the rotor inertia (``armature``), viscous (``damping``) and
Coulomb friction (``frictionloss``, MuJoCo's soft friction constraint, close to the tanh model away
from velocity reversals); URDF keeps the rigid body and ``<dynamics damping friction>`` but has no
rotor inertia. Neither has load-dependent, Stribeck or square-root viscous friction, a constant
offset, or a presliding (Dahl) / hold friction state; of a stateful Coulomb model only its tanh
version is kept, and the difference is listed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from urident.model.parameters import COULOMB_KIND, RIGID_BODY_KIND, ROTOR_KIND, VISCOUS_KIND

FORMATS = ("mjcf", "urdf")
#: Column kinds each format expresses.
EXPRESSIBLE = {
    "mjcf": frozenset({RIGID_BODY_KIND, ROTOR_KIND, VISCOUS_KIND, COULOMB_KIND}),
    "urdf": frozenset({RIGID_BODY_KIND, VISCOUS_KIND, COULOMB_KIND}),
}
DESCRIPTIONS = {
    ROTOR_KIND: "reflected rotor inertia i_G^2*C_M (no URDF element)",
    "offset": "constant torque offset",
    "stribeck": "Stribeck friction (static above Coulomb near zero velocity)",
    "dahl": "presliding (Dahl) friction state",
    "load_friction": "load-dependent Coulomb friction",
    "sqrt_viscous": "square-root viscous friction sign(qd)*sqrt|qd|",
    "coulomb_asymmetry": "Coulomb asymmetry |z|",
    "sigmoid": "sigmoid Coulomb friction tanh(qd/eps) of its own smoothness",
    "sigmoid_offset": "sigmoid offset tanh(qd/eps)^2 (direction-dependent friction)",
    "quadratic_viscous": "quadratic viscous friction qd*|qd|",
    "position_friction": "position-dependent Coulomb friction z*cos/sin(k*q)",
    "temperature_viscous": "temperature-dependent viscous friction qd*(T-T_ref)",
    "temperature_coulomb": "temperature-dependent Coulomb friction z*(T-T_ref)",
    "coulomb_state": "Coulomb friction state ({model}) beyond tanh(qd/eps)",
}


def expressible(fmt: str, kind: str) -> bool:
    """Whether format ``fmt`` ('mjcf' or 'urdf') can express a term of ``kind``."""
    return kind in EXPRESSIBLE[fmt]


@dataclass(frozen=True)
class Term:
    """An identified term a format cannot express; ``share_pct`` (6,): RMS of its torque over the
    RMS of the measured torque per joint [%] (None without data)."""

    kind: str
    description: str
    joints: tuple[int, ...]          # 0-based joints where it is identified non-zero
    share_pct: np.ndarray | None

    def line(self) -> str:
        share = ("share of the validation torque: n/a (no validation log)" if self.share_pct is None
                 else "share of the validation torque per joint: "
                 + " ".join(f"{v:.1f}%" for v in self.share_pct))
        return f"not expressed: {self.description}; {share}"


def inexpressible_terms(params, spec, fmt: str, data=None) -> list[Term]:
    """The terms of ``params`` (an IdentifiedModel) that ``fmt`` cannot express, each with its share
    of the measured torque of ``data`` (a :class:`urident.ident.preprocess.Prepared`, optional)."""
    kinds = np.array(params.kinds)
    values = np.asarray(params.values, dtype=float)
    groups = [k for k in dict.fromkeys(kinds) if not expressible(fmt, k) and k != "unknown"]
    stateful = params.model.coulomb != "tanh" or any(c != "tanh" for c in params.model.joint_coulomb)
    if not groups and not stateful:
        return []
    blocks = contributions = None
    if data is not None:
        from urident.ident.design import design_blocks

        blocks = design_blocks(spec, params.model, data.q, data.qd, data.qdd, data.segment, data.t,
                               temperature=data.temperature)
        contributions = blocks * values          # (N, 6, n) torque of each column
        tau_rms = np.sqrt(np.mean(data.tau ** 2, axis=0))
        tau_rms[tau_rms == 0] = np.inf
    terms = []

    def add(kind, description, mask, torque):
        joints = tuple(int(j) for j in range(6) if np.any(np.abs(torque[:, j]) > 0)) if torque is not None \
            else tuple(range(6))
        share = None if torque is None else 100.0 * np.sqrt(np.mean(torque ** 2, axis=0)) / tau_rms
        terms.append(Term(kind, description, joints, share))

    for kind in groups:
        if RIGID_BODY_KIND == kind:
            continue
        mask = kinds == kind
        if not np.any(values[mask] != 0):
            continue
        torque = None if contributions is None else contributions[:, :, mask].sum(axis=2)
        add(kind, DESCRIPTIONS.get(kind, kind), mask, torque)
    if stateful and COULOMB_KIND in EXPRESSIBLE[fmt]:
        mask = kinds == COULOMB_KIND
        torque = None
        if contributions is not None:
            # the format keeps fc*tanh(qd/eps): what the state adds beyond it is lost
            cols = np.flatnonzero(mask)
            kept = np.zeros_like(data.tau)
            for c in cols:
                j = int(np.argmax(np.any(blocks[:, :, c] != 0, axis=0)))
                kept[:, j] += values[c] * np.tanh(data.qd[:, j] / params.model.friction_eps)
            torque = contributions[:, :, mask].sum(axis=2) - kept
        add("coulomb_state", DESCRIPTIONS["coulomb_state"].format(model=params.model.coulomb_text()), mask, torque)
    return terms
