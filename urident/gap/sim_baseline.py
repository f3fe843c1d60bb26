"""A user's simulator model (MJCF or URDF, :mod:`urident.sim.models`) as the gap's baseline.

The baseline is the model as it is, not refitted: τ̂ = the simulator's inverse dynamics on the
validation logs' states (MuJoCo's ``mj_inverse`` for MJCF, Pinocchio + ``<dynamics>`` for URDF).
With no refit on identification logs every candidate is fitted inside the validation logs (CV
mode). Beside the catalogue, the candidates a simulator model typically needs, per joint j:

=============  ==========================================  ===================================
armature       q̈_j                                         joint ``armature`` (MJCF only)
damping        q̇_j                                         ``damping``
frictionloss   tanh(q̇_j/ε)                                 ``frictionloss`` / ``friction``
rigid_body     body j's m, m·ρ columns of the regressor      link ``<inertial>`` mass and CoM
link_inertia   body j's inertia columns (A … F about K_j)    link ``<inertial>`` inertia
               the data separate from armature j
=============  ==========================================  ===================================

Link inertia against armature: when joint j's axis is perpendicular to every earlier axis (joint 1
always; joint 2 of a UR arm) the link's inertia about its own axis enters the dynamics exactly as
the joint's armature does (only as I·q̈_j on joint j), so neither the data nor the simulator can tell
them apart: :func:`link_inertia_columns` keeps only the inertia columns that are not a combination
of armature j and the columns kept before (on the validation states), and the armature finding
then holds rotor inertia plus that part of the link's inertia error (the report says so).

plus ``payload_error`` (a body on the flange) and ``torque_constant_error`` (a drive gain scale,
a property of the measurement, which no simulator format holds). :func:`expressible` says which
findings a format can take; :func:`corrections` turns the expressible ones into the changes
:mod:`urident.sim.correct` writes.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from urident.gap.candidates import Candidate, families, payload_error, torque_constant_error
from urident.gap.config import GapConfig
from urident.gap.data import build_set
from urident.gap.residual import SetContext, smooth_derivative
from urident.ident.design import ModelConfig

SIM_EFFECTS = ("armature", "damping", "frictionloss", "rigid_body", "link_inertia")
#: the joint drive terms a downloaded model lacks most often; selected before the link terms
DRIVE_EFFECTS = ("armature", "damping", "frictionloss")
#: Findings each format can express (the rest: the catalogue's effects, a drive gain scale).
EXPRESSIBLE = {"mjcf": frozenset({"armature", "damping", "frictionloss", "rigid_body", "link_inertia",
                                  "payload_error"}),
               "urdf": frozenset({"damping", "frictionloss", "rigid_body", "link_inertia", "payload_error"})}
#: body parameters A … F (inertia about K_j) within body_slice(j)
INERTIA_FIELDS = ("A", "B", "C", "D", "E", "F")
#: a column is "a combination of the others" when its part outside their span is below this share
ALIAS_TOL = 1e-6


def expressible(fmt: str, effect: str) -> bool:
    return effect in EXPRESSIBLE[fmt]


@dataclass(frozen=True)
class SimBaseline:
    """What the report and JSON say about the baseline (an IdentifiedModel's ``method``/``model``)."""

    method: str
    model: ModelConfig
    fmt: str
    path: str

    def summary(self) -> str:
        """The baseline in the report's first line."""
        return f"{self.method}, as it is, through its own inverse dynamics"


class SimCandidate(Candidate):
    def magnitude(self, beta, spec=None) -> dict:
        b = [float(x) for x in np.asarray(beta, float)]
        out: dict = {"coefficients": b}
        if self.effect == "armature":
            out["armature_kg_m2"] = b[0]
        elif self.effect == "damping":
            out["damping_nm_s_per_rad"] = b[0]
        elif self.effect == "frictionloss":
            out["frictionloss_nm"] = b[0]
        elif self.effect == "rigid_body":
            out.update(mass_change_kg=b[0], first_moment_change_kg_m=b[1:4])
        elif self.effect == "link_inertia":
            out.update(inertia_change_kg_m2=inertia_change(self, beta).tolist())
            if self.settings.get("aliased"):
                out.update(folded_into_armature=list(self.settings["aliased"]))
        return out


def inertia_change(c: Candidate, beta) -> np.ndarray:
    """(3, 3) change of link ``c.joint``'s inertia about K_j (K_j's axes) for a ``link_inertia``
    candidate's coefficients (its dropped columns change nothing)."""
    from urident.model.parameters import inertia_tensor

    p10 = np.zeros(10)
    p10[[4 + INERTIA_FIELDS.index(f) for f in c.settings["fields"]]] = np.asarray(beta, float)
    return inertia_tensor(p10)


def _on_joint(ctx, j, column) -> np.ndarray:
    out = np.zeros((ctx.n, 6, 1))
    out[:, j, 0] = column
    return out


def _regressor(ctx, spec) -> np.ndarray:
    key = "sim_regressor"
    if key not in ctx.cache:
        from urident.model import regressor_blocks

        ctx.cache[key] = regressor_blocks(spec, ctx.q, ctx.qd, ctx.qdd, ctx.friction_eps)
    return ctx.cache[key]


def sim_candidates(spec) -> list[list[Candidate]]:
    """One family per (simulator effect, joint), all CV mode."""
    from urident.model.parameters import body_slice

    out = []
    for j in range(6):
        out.append([SimCandidate("armature", j, "", "cv", ("qdd",), lambda c, j=j: _on_joint(c, j, c.qdd[:, j]))])
        out.append([SimCandidate("damping", j, "", "cv", ("qd",), lambda c, j=j: _on_joint(c, j, c.qd[:, j]))])
        out.append([SimCandidate("frictionloss", j, "", "cv", ("tanh(qd/eps)",),
                                 lambda c, j=j: _on_joint(c, j, c.sign()[:, j]))])
        cols = slice(body_slice(j).start, body_slice(j).start + 4)
        out.append([SimCandidate("rigid_body", j, f"link {j + 1} mass and centre of mass", "cv",
                                 ("m", "m*rho_x", "m*rho_y", "m*rho_z"),
                                 lambda c, cols=cols: _regressor(c, spec)[:, :, cols])])
    return out


def link_inertia_columns(spec, ctx, j: int) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """(kept, aliased): body j's inertia fields (A … F) that the validation states tell apart from
    armature j and from each other, and those that are a combination of armature j (and the kept
    ones) there, i.e. cannot be separated from it; fields with no effect at all are in neither."""
    from urident.model.parameters import body_slice

    y = _regressor(ctx, spec)
    start = body_slice(j).start + 4
    arm = np.zeros((ctx.n, 6))
    arm[:, j] = ctx.qdd[:, j]
    basis = [arm.reshape(-1) / max(np.linalg.norm(arm), 1e-300)]
    kept, aliased = [], []
    for k, name in enumerate(INERTIA_FIELDS):
        col = y[:, :, start + k].reshape(-1)
        norm = np.linalg.norm(col)
        if not norm > 0:
            continue
        rest = col - np.column_stack(basis) @ (np.column_stack(basis).T @ col)
        rest -= np.column_stack(basis) @ (np.column_stack(basis).T @ rest)   # once more: orthogonal to 1e-16
        if np.linalg.norm(rest) <= ALIAS_TOL * norm:
            # needing armature j to express it: inseparable from it (else a regrouping inside the link)
            own = np.column_stack(basis[1:]) if len(basis) > 1 else np.zeros((col.size, 0))
            if np.linalg.norm(col - own @ (own.T @ col)) > ALIAS_TOL * norm:
                aliased.append(name)
            continue
        kept.append(name)
        basis.append(rest / np.linalg.norm(rest))
    return tuple(kept), tuple(aliased)


LINK_EFFECTS = ("rigid_body", "link_inertia")


def off_armature(c: Candidate, ctx) -> Candidate:
    """``c`` (a link correction) with the part of its columns that the armature columns q̈_k (on
    joint k's rows) express taken off, on the validation states: a link's mass or inertia also acts
    as inertia about every earlier joint, nearly as a constant there, and would take over the
    joints' missing armature. The correction then explains only what armature cannot; its
    coefficients β change the link by β and armature k by −β·α_k (``settings["armature_alpha"]``,
    (k, 6)), which :func:`corrections` writes, so the simulator reproduces the projected columns."""
    x = c.features(ctx)                                      # (N, 6, k)
    qdd = ctx.qdd
    denom = np.sum(qdd ** 2, axis=0)
    alpha = np.einsum("nji,nj->ij", x, qdd) / np.where(denom > 0, denom, np.inf)   # (k, 6)

    def build(cx, raw=c.build, alpha=alpha):
        return np.asarray(raw(cx), float) - cx.qdd[:, :, None] * alpha.T[None, :, :]
    return SimCandidate(c.effect, c.joint, c.variant, c.mode, c.columns, build,
                        {**c.settings, "armature_alpha": alpha})


def link_inertia_candidates(spec, ctx) -> list[list[Candidate]]:
    """One ``link_inertia`` family per link whose inertia the validation states can see."""
    from urident.model.parameters import body_slice

    out = []
    for j in range(6):
        kept, aliased = link_inertia_columns(spec, ctx, j)
        if not kept:
            continue
        cols = [body_slice(j).start + 4 + INERTIA_FIELDS.index(f) for f in kept]
        out.append([SimCandidate("link_inertia", j, f"link {j + 1} inertia", "cv", kept,
                                 lambda c, cols=cols: _regressor(c, spec)[:, :, cols],
                                 {"fields": kept, "aliased": aliased})])
    return out


def drive_fit(tau_hat, p, friction_eps: float = 0.01) -> np.ndarray:
    """(N, 6) least-squares fit of armature, damping and Coulomb friction per joint to the measured
    minus predicted torque of ``p`` (a Prepared)."""
    out = np.zeros_like(tau_hat)
    for j in range(6):
        x = np.column_stack([p.qdd[:, j], p.qd[:, j], np.tanh(p.qd[:, j] / friction_eps)])
        out[:, j] = x @ np.linalg.lstsq(x, p.tau[:, j] - tau_hat[:, j], rcond=None)[0]
    return out


def make_sim_context(sim, data) -> SetContext:
    p = data.prepared
    tau_hat = sim.predict(p.q, p.qd, p.qdd)
    tau_link = sim.rigid(p.q, p.qd, p.qdd)
    # current_delay delays the whole drive torque: a model without armature, damping or friction
    # would leave their delay (−d·b·q̈ looks like armature, −d·∂τ/∂q·q̇ like damping) to the drive
    # terms, so its column is the derivative of the prediction with them fitted per joint
    dtau = smooth_derivative(tau_hat + drive_fit(tau_hat, p, sim.friction_eps), p.t, p.segment, 1)
    ddtau = smooth_derivative(tau_link, p.t, p.segment, 2)
    # one column (the prediction) stands in for a design matrix: nothing is refitted
    return SetContext(data, tau_hat.reshape(-1, 1), tau_hat, tau_link, dtau, ddtau, float(sim.friction_eps), {})


def diagnose_sim(valid_recordings: Sequence, spec, sim, *, drive_gains=None,
                 config: GapConfig | None = None):
    """The diagnosis (where / which / how far) of ``sim`` (a :class:`urident.sim.models.SimModel`) on
    the validation recordings; a :class:`urident.gap.results.GapResult` whose ``model`` is a
    :class:`SimBaseline`."""
    from urident.gap.bootstrap import default_block_length
    from urident.gap.results import GapResult, e_n, rms
    from urident.gap.scoring import Scorer
    from urident.gap.selection import select
    from urident.gap.significance import unit_gain_variants
    from urident.gap.where import describe_where

    config = config or GapConfig()
    from urident.gap.events import find_events, smooth_basis, without_events

    valid = build_set(valid_recordings, spec, drive_gains, None, "validation logs")
    ctx = make_sim_context(sim, valid)
    n_valid = ctx.n
    events = find_events(ctx.residual, valid.run_time, valid.prepared.qd, valid.sample_rate,
                         smooth_basis(ctx))
    if events:       # contact, collisions, stalls: set aside (urident.gap.events)
        valid = without_events(valid, events)
        ctx = make_sim_context(sim, valid)
    scorer = Scorer(ctx, ctx, config.n_folds)
    where = describe_where(ctx, ctx)
    fams = sim_candidates(spec) + link_inertia_candidates(spec, ctx)
    if expressible(sim.fmt, "armature"):
        fams = [[off_armature(c, ctx) if c.effect in LINK_EFFECTS else c for c in fam] for fam in fams]
    fams.append([payload_error(spec, "cv")])
    fams += [[torque_constant_error(j, "cv")] for j in range(6)]
    seen = {("payload_error", None)} | {("torque_constant_error", j) for j in range(6)}
    others = [e for e in config.effects if e not in ("payload_error", "torque_constant_error")]
    for fam in families(spec, ctx, ctx, others):
        if fam[0].mode == "ident" and fam[0].key not in seen:     # no refit: every effect in CV mode
            for c in fam:
                c.mode = "cv"
        if fam[0].mode == "cv" and fam[0].key not in seen:
            seen.add(fam[0].key)
            fams.append(fam)
    fams = [unit_gain_variants(f, scorer) for f in fams]
    pool = [max(f, key=scorer.training_gain) if len(f) > 1 else f[0] for f in fams if f]
    block = default_block_length(ctx.n, valid.sample_rate * config.block_s)
    r0 = ctx.residual
    baseline = SimBaseline(f"{sim.fmt} model {sim.path.name}", ModelConfig(friction_eps=sim.friction_eps),
                           sim.fmt, str(sim.path))
    while True:
        # a joint's drive terms first: a link's mass/CoM column also acts as inertia about earlier
        # joints (link 2's mass at the elbow as armature of joints 1-2), and taken first it soaks up
        # their missing armature with an unphysical mass (+10.7 kg on the UR5e's 8 kg link 2)
        findings, steps, confounds, current = select(scorer, pool, block, config, ctx, spec,
                                                     prefer=lambda c: c.effect in DRIVE_EFFECTS)
        result = GapResult(spec.name, baseline, ctx, ctx, e_n(r0), rms(r0), e_n(current.residual),
                           rms(current.residual), findings, current, steps, confounds, where, config, scorer,
                           events, n_valid)
        # a link correction that is no real mass distribution (alone or with only the expressible
        # findings) holds what other terms should: select again without it
        bad = unrealisable_chosen(result, sim, spec)
        if not bad:
            return result
        pool = [c for c in pool if not any(c is b for b in bad)]


def unrealisable_chosen(result, sim, spec) -> list[Candidate]:
    """The chosen rigid_body / link_inertia candidates whose correction (in the fit of all chosen
    ones, or of the expressible ones alone) is not a real mass distribution."""
    from urident.sim.correct import unrealisable_links

    chosen = result.chosen()
    changes = corrections(result)
    links = set(unrealisable_links(sim, spec, changes))
    bad = unwritable(chosen, links, changes)
    if result.model.fmt in EXPRESSIBLE:
        changes = corrections(result, expressible_fit(result)[0])
        bad += [c for c in unwritable(chosen, set(unrealisable_links(sim, spec, changes)), changes) if c not in bad]
    return bad


def unwritable(candidates, links, changes) -> list[Candidate]:
    """The candidates behind the unrealisable ``links`` (0-based) of ``changes``: a link's own
    corrections, and a negative payload (written into link 6)."""
    payload = changes.get("payload")
    negative = payload is not None and payload[0] <= 0
    return [c for c in candidates if (c.effect in LINK_EFFECTS and c.joint in links)
            or (c.effect == "payload_error" and negative and 5 in links)]


@dataclass(frozen=True, eq=False)
class SimCorrections(Mapping):
    """Additions to a simulator model's values (what :mod:`urident.sim.correct` writes), also read
    as a mapping by name: ``armature``, ``damping``, ``frictionloss`` (6,), ``mass`` (6,) [kg],
    ``first_moment`` (6, 3) [kg·m], ``inertia`` (6, 3, 3) about K_j in K_j's axes [kg·m²],
    ``payload`` (mass [kg], first moment (3,) [kg·m]) or None."""

    armature: np.ndarray
    damping: np.ndarray
    frictionloss: np.ndarray
    mass: np.ndarray
    first_moment: np.ndarray
    inertia: np.ndarray
    payload: tuple | None = None

    def __getitem__(self, key: str):
        if key not in self.__dataclass_fields__:
            raise KeyError(key)
        return getattr(self, key)

    def __iter__(self):
        return iter(self.__dataclass_fields__)

    def __len__(self) -> int:
        return len(self.__dataclass_fields__)


def corrections(result, candidates=None) -> SimCorrections:
    """The expressible findings of a :func:`diagnose_sim` result (or only ``candidates`` of them,
    refitted together) as model changes:
    ``{"armature": (6,), "damping": (6,), "frictionloss": (6,), "mass": (6,), "first_moment": (6, 3),
    "inertia": (6, 3, 3) about K_j in K_j's axes, "payload": (mass, first moment (3,)) or None}``
    (additions to the model's values)."""
    fmt = result.model.fmt
    out = {"armature": np.zeros(6), "damping": np.zeros(6), "frictionloss": np.zeros(6),
           "mass": np.zeros(6), "first_moment": np.zeros((6, 3)), "inertia": np.zeros((6, 3, 3)),
           "payload": None}
    fit = result.fit if candidates is None else result.correction(list(candidates))
    for c, beta in fit.coefficients().items():
        if not expressible(fmt, c.effect):
            continue
        if "armature_alpha" in c.settings:
            out["armature"] -= np.asarray(beta, float) @ c.settings["armature_alpha"]
        if c.effect in ("armature", "damping", "frictionloss"):
            out[c.effect][c.joint] += beta[0]
        elif c.effect == "rigid_body":
            out["mass"][c.joint] += beta[0]
            out["first_moment"][c.joint] += beta[1:4]
        elif c.effect == "link_inertia":
            out["inertia"][c.joint] += inertia_change(c, beta)
        elif c.effect == "payload_error":
            out["payload"] = (float(beta[0]), np.asarray(beta[1:4], float))
    return SimCorrections(**out)


def expressible_fit(result):
    """The chosen candidates the format can express, fitted together on all validation samples."""
    chosen = [c for c in result.chosen() if expressible(result.model.fmt, c.effect)]
    return chosen, result.correction(chosen)


#: units of the drive terms' values
DRIVE_UNITS = {"armature": "kg·m²", "damping": "N·m·s/rad", "frictionloss": "N·m"}


@dataclass(frozen=True)
class DetectionLimit:
    """A drive term not found, and the value below which these states would not show it."""

    effect: str
    joint: int              # 1-based
    unit: str
    below_nm: float         # its torque RMS at the limit [N·m]
    limit: float            # the value, in ``unit``
    column_rms: float       # RMS of its column (q̈, q̇ or tanh(q̇/ε)) on the states

    def as_dict(self) -> dict:
        return {"effect": self.effect, "joint": self.joint, "unit": self.unit, "below_nm": self.below_nm,
                "limit": self.limit, "column_rms": self.column_rms}


def detection_limits(result) -> list[DetectionLimit]:
    """The drive terms of the format (armature, damping, frictionloss per joint) that are not among
    the findings, each with the smallest value these validation states would have shown: its
    torque must reach ``cv_min_noise_ratio`` × the joint's white-noise torque and shrink the
    joint's remaining RMS by ``min_shrink_pct`` (an uncorrelated term of RMS a shrinks R to
    √(R² − a²)); below that it is not identifiable here, not shown to be absent."""
    from urident.gap.significance import noise_sigma

    ctx, config = result.valid, result.config
    found = {(f.effect, f.joint - 1) for f in result.findings}
    sigma = noise_sigma(ctx.residual)
    keep = 1.0 - config.min_shrink_pct / 100.0
    cols = {"armature": ctx.qdd, "damping": ctx.qd, "frictionloss": ctx.sign()}
    out = []
    for effect in DRIVE_EFFECTS:
        unit = DRIVE_UNITS[effect]
        if not expressible(result.model.fmt, effect):
            continue
        col_rms = np.sqrt(np.mean(cols[effect] ** 2, axis=0))
        for j in range(6):
            if (effect, j) in found:
                continue
            torque = max(config.cv_min_noise_ratio * sigma[j], result.final_rms[j] * np.sqrt(1 - keep ** 2))
            limit = torque / col_rms[j] if col_rms[j] > 0 else float("inf")
            out.append(DetectionLimit(effect, j + 1, unit, float(torque), float(limit), float(col_rms[j])))
    return out
