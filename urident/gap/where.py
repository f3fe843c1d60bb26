"""Where the residual lies: per-joint RMS, share of the energy, maps, spectra and the regimes
where it concentrates (:func:`describe_where`), and where a finding's improvement lies
(:func:`finding_regime`)."""

from __future__ import annotations

import numpy as np

from urident.gap import maps
from urident.gap.controller import controller_reference
from urident.gap.residual import SetContext
from urident.gap.results import Score
from urident.gap.significance import noise_sigma

#: The map axes where each effect's improvement is looked for first.
PREFER_AXIS = {"stribeck": ("velocity",), "load_friction": ("load",), "quadratic_viscous": ("velocity",),
               "neighbour_load_friction": ("velocity",), "thermal_drift": ("time",),
               "position_ripple": ("angle",), "current_offset": ("velocity", "angle"),
               "torque_constant_error": ("load",), "payload_error": ("angle",),
               "current_delay": (), "joint_elasticity": (), "asymmetric_coulomb": ("velocity",),
               "current_lag": ()}


def signed_load(ctx: SetContext) -> np.ndarray:
    """(N, 6) sign(q̇)·|τ̂|: the load axis of the maps."""
    return np.sign(ctx.qd) * np.abs(ctx.tau_hat)


def finding_regime(best: Score, ctx: SetContext, joint: int | None = None) -> str:
    """The text of where ``best``'s improvement on its joint (or 0-based ``joint``) concentrates
    (``ctx``: validation)."""
    c = best.candidate
    j = best.joint if joint is None else joint
    base_r = best.change + best.fit.residual          # residual before this step
    gain_j = base_r[:, j] ** 2 - best.fit.residual[:, j] ** 2
    reg = maps.best_regime(j, gain_j, ctx.qd[:, j], signed_load(ctx)[:, j], ctx.q[:, j],
                           ctx.data.run_time, PREFER_AXIS.get(c.effect, ()))
    if reg is not None:
        regime = reg.text("of the improvement")
    else:
        regime = f"joint {j + 1}: spread over all regimes"
    if c.effect == "current_delay":
        fm = maps.frequency_map(base_r[:, j], ctx.data.sample_rate, ctx.dtau[:, j])
        regime += f"; residual vs dτ̂/dt correlation {fm.corr_dtau:+.2f}"
    return regime


def describe_where(ctx: SetContext, ident: SetContext | None = None) -> dict:
    """Per joint: RMS, share of the residual energy, maps, angle spectrum, frequency map and the
    regimes where the residual concentrates (texts)."""
    r = ctx.residual
    energy = np.sum(r * r, axis=0)
    total = float(energy.sum()) or 1.0
    load = signed_load(ctx)
    out = {"joints": []}
    fs = ctx.data.sample_rate
    for j in range(6):
        jm = maps.joint_maps(r[:, j], ctx.qd[:, j], load[:, j], ctx.q[:, j], ctx.data.run_time)
        regimes = maps.concentrated_regimes(j, jm)
        spec_a = maps.angle_spectrum(r[:, j], ctx.q[:, j], ctx.qd[:, j], ctx.friction_eps)
        fm = maps.frequency_map(r[:, j], fs, ctx.dtau[:, j])
        out["joints"].append({
            "joint": j + 1, "rms_nm": float(np.sqrt(energy[j] / len(r))),
            "energy_share": float(energy[j] / total), "mean_nm": float(r[:, j].mean()),
            "maps": {k: [b.as_dict() for b in v] for k, v in jm.items()},
            "angle_spectrum": spec_a.as_dict(), "frequency": fm.as_dict(),
            "regimes": [g.text() for g in regimes]})
    out["controller_model"] = controller_reference(ctx, ident)
    return out


#: A joint's residual left after the findings is reported as beyond the catalogue when its RMS is
#: at least this multiple of the joint's white-noise torque (noise alone gives 1; effect-free
#: simulated runs stay below it, the real UR10e pair shows 1.4-6 on every joint).
UNEXPLAINED_NOISE_RATIO = 1.25


def describe_unexplained(ctx: SetContext, residual: np.ndarray,
                         ratio: float = UNEXPLAINED_NOISE_RATIO, min_shrink_pct: float = 3.0,
                         noise_ratio: float = 0.5, ident_structure: dict | None = None) -> list[dict]:
    """Joints whose residual ``residual`` (N, 6; validation, after the named effects) still carries
    structure: its RMS at least ``ratio`` times the white-noise torque, or a structure a white-noise
    test does not see (:func:`urident.gap.structure.joint_structure`: harmonics of the angle up to
    the angle-Nyquist, dependence on a joint's velocity, the model torque or time, localisation in
    time) that would shrink it by ``min_shrink_pct`` with a fitted part of ``noise_ratio`` × the
    noise. Each with its RMS, the noise, the structured part √(RMS² − σ²), the structures and the
    regimes of the maps where it concentrates, so that an effect beyond the catalogue is reported
    instead of silently missing. ``ident_structure`` (0-based joint → entry of
    :func:`urident.gap.structure.identification_only`): structure the identification logs hold on
    a joint whose validation residual does not show it; such a joint is listed too."""
    from urident.gap.structure import describe, joint_structure

    r = np.asarray(residual, float)
    sigma = noise_sigma(r)
    load = signed_load(ctx)
    out = []
    for j in range(r.shape[1]):
        rms_j = float(np.sqrt(np.mean(r[:, j] ** 2)))
        if sigma[j] <= 0:
            continue
        found = joint_structure(j, r[:, j], ctx, float(sigma[j]), min_shrink_pct, noise_ratio)
        if ident_structure and j in ident_structure:
            found.append(dict(ident_structure[j]))
        if rms_j < ratio * sigma[j] and not found:
            continue
        jm = maps.joint_maps(r[:, j], ctx.qd[:, j], load[:, j], ctx.q[:, j], ctx.data.run_time)
        regimes = maps.concentrated_regimes(j, jm)
        for f in found:
            f["text"] = describe(f)
        out.append({"joint": j + 1, "rms_nm": rms_j, "noise_nm": float(sigma[j]),
                    "noise_ratio": float(rms_j / sigma[j]),
                    "structured_rms_nm": float(np.sqrt(max(rms_j ** 2 - sigma[j] ** 2, 0.0))),
                    "structure": found,
                    "regimes": [g.text("of the remaining energy") for g in regimes]})
    return out
