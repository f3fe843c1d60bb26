"""Joint torques from motor currents, τ_i = i_G,i·k_i·I_i (paper section IV-C), and estimation of
the drive gains i_G,i·k_i from two runs, with and without a known payload.

Drive-gain estimation. Without payload K·I₀ = Θ_B(x₀)·p_B; with a payload of known mass, centre
of mass (and optionally inertia) rigidly attached to the last body, K·I₁ = Θ_B(x₁)·p_B + τ_P(x₁),
where τ_P = Θ_6(x₁)·Δp₆ is the payload's torque (Θ_6: the regressor columns of body 6, Δp₆ the
payload's ten parameters about K_6). Both are linear in the unknowns (p_B, K): the stacked
least-squares problem

    [ Θ_B(x₀)  −diag(I₀) ] [p_B]   [   0    ]
    [ Θ_B(x₁)  −diag(I₁) ] [ K ] = [ −τ_P(x₁) ]

has a unique solution when both runs excite the base parameters and the payload torque is not
negligible; the scale of K comes from the payload alone. Because the currents appear in the matrix,
plain least squares is biased by their noise; the estimate is refined by instrumental variables
(instruments: the currents predicted by the previous fit).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from urident.errors import ConfigError


def resolve_drive_gains(spec, drive_gains: Sequence[float] | None = None) -> np.ndarray:
    """The drive gains to use: ``drive_gains`` if given, else the robot file's ``gear·k``."""
    if drive_gains is None:
        return np.array(spec.drive_gains, dtype=float)
    g = np.asarray(drive_gains, dtype=float)
    if g.shape != (6,) or not np.all(np.isfinite(g)) or np.any(g <= 0):
        raise ConfigError(f"drive gains must be six positive numbers, got {drive_gains!r}")
    return g


def torque_from_current(current: np.ndarray, drive_gains: np.ndarray) -> np.ndarray:
    """(N, 6) joint torques [N·m] from (N, 6) motor currents [A]."""
    return np.asarray(current, dtype=float) * np.asarray(drive_gains, dtype=float)


#: Where the joint torques of a recording come from (``--signal``; docs/signals.md):
#: ``current`` motor current x drive gains; ``torque`` the log's full joint torques (a bag read
#: with ``--effort torque``); ``compensated`` UR's gravity-compensated torque
#: (actual_current_as_torque, a bag read with ``--effort compensated``) with the nominal model's
#: gravity added back, so masses and first moments come from the model, not from the data.
SIGNALS = ("current", "torque", "compensated")

#: ``Recording.metadata["torque_kind"]``: what the recording's joint torques are.
TORQUE_KINDS = ("full", "compensated")


def torque_kind(recording) -> str | None:
    """``full`` or ``compensated`` (UR's actual_current_as_torque), None without torques. A
    recording that does not say (built in code) holds full torques."""
    if recording.tau is None:
        return None
    return recording.metadata.get("torque_kind") or "full"


def torque_invalid(recording) -> str | None:
    """Why the recording's joint torques (``Recording.tau``: RTDE actual_current_as_torque or a
    bag's torque effort) cannot be used, or None when they can."""
    tau = recording.tau
    if tau is None:
        return "the log carries no joint torque"
    if not np.all(np.isfinite(tau)):
        return "its joint torques hold NaN/inf"
    if not np.any(tau):  # a controller that lists the field but never fills it
        return "its joint torques are all zero"
    return None


def torque_signal(recording, signal: str | None = None) -> str:
    """The signal the torques of ``recording`` come from: ``signal`` if given (or the
    ``--signal`` its loader recorded, ``metadata["signal"]``), else ``torque`` when the log
    carries valid full joint torques, else ``current``. A gravity-compensated torque is never the
    default: fitted as if full it gives wrong masses and first moments without a word."""
    signal = signal or recording.metadata.get("signal")
    why = torque_invalid(recording)
    kind = torque_kind(recording)
    if kind == "compensated" and recording.metadata.get("current_from_torque") and signal in (None, "current"):
        raise ConfigError(f"{recording.source}: its effort is a gravity-compensated torque and "
                          "carries no motor current; pass --signal compensated (gravity terms are "
                          "then the nominal model's, not identified)")
    if signal is None:
        return "torque" if why is None and kind == "full" else "current"
    if signal not in SIGNALS:
        raise ConfigError(f"signal {signal!r}: expected one of {', '.join(SIGNALS)}")
    if signal != "current" and why:
        raise ConfigError(f"{recording.source}: --signal {signal}: {why}; use --signal current")
    if signal == "torque" and kind == "compensated":
        raise ConfigError(f"{recording.source}: --signal torque: its joint torques are "
                          "gravity-compensated (UR's actual_current_as_torque), not full torques; "
                          "use --signal current (default) or --signal compensated")
    if signal == "compensated" and kind == "full":
        raise ConfigError(f"{recording.source}: --signal compensated: its joint torques are full "
                          "torques; use --signal torque")
    return signal


def restored_gravity(recording, spec) -> np.ndarray:
    """(N, 6) gravity torque [N·m] the controller took out of a compensated torque, as urident
    can know it: the robot file's nominal model, plus the payload declared to the controller
    during the run (sidecar), at the recorded positions."""
    from urident.logs.sidecar import declared_payload
    from urident.model.regressor import joint_torques

    q = np.asarray(recording.q, dtype=float)
    zero = np.zeros_like(q)
    gravity = joint_torques(spec, spec.nominal_params, q, zero, zero)
    p = declared_payload(dict(recording.metadata))
    if p is not None and p.mass_kg > 0:  # its gravity needs mass and centre of mass only
        from urident.model import regressor_blocks
        from urident.model.parameters import TOOL_BODY, body_params

        com = np.asarray(spec.tool_xyz, float) + np.asarray(spec.tool_rotation, float) @ np.asarray(p.cog_m)
        load = body_params(p.mass_kg, com, np.zeros((3, 3)))  # flange frame → K_6
        gravity = gravity + regressor_blocks(spec, q, zero, zero)[:, :, TOOL_BODY] @ load
    return gravity


def measured_torque(recording, drive_gains: np.ndarray, signal: str | None = None,
                    spec=None) -> np.ndarray:
    """(N, 6) joint torques [N·m] of ``recording`` by :func:`torque_signal`: the motor currents
    times ``drive_gains``, the recorded full joint torques, or the compensated torques plus
    :func:`restored_gravity` (needs ``spec``)."""
    chosen = torque_signal(recording, signal)
    if chosen == "torque":
        return np.asarray(recording.tau, dtype=float)
    if chosen == "compensated":
        if spec is None:
            raise ConfigError("--signal compensated needs the robot model to restore the gravity")
        return np.asarray(recording.tau, dtype=float) + restored_gravity(recording, spec)
    return torque_from_current(recording.current, drive_gains)


#: What each signal can identify, for reports and parameter files.
SIGNAL_TEXT = {
    "current": "motor current x drive gains",
    "torque": "the recorded full joint torques",
    "compensated": ("the gravity-compensated joint torques + the nominal model's gravity: masses "
                    "and first moments (gravity terms) are the model's, not identified; inertia "
                    "and friction are"),
}


def describe_signal(recording, signal: str | None = None) -> str:
    """One line for reports: which signal gave the torques, the correction applied, and why."""
    name = recording.source.name if recording.source is not None else "log"
    signal = signal or recording.metadata.get("signal")
    chosen = torque_signal(recording, signal)
    text = f"torques of {name}: {SIGNAL_TEXT[chosen]}"
    if chosen != "current":
        return text
    why = torque_invalid(recording)
    if signal == "current" or recording.tau is None:
        return text
    if why is None and torque_kind(recording) == "compensated":
        why = ("its joint torques are gravity-compensated (actual_current_as_torque), not used; "
               "--signal compensated uses them without gravity terms")
    return f"{text} ({why})" if why else text


@dataclass(frozen=True)
class DriveGainEstimate:
    gains: np.ndarray        # (6,) [N·m/A]
    sigma: np.ndarray        # (6,) standard deviations
    base_params: np.ndarray  # (b,) base parameters of the arm without payload


#: An estimated drive gain beyond this factor of the robot file's is no drive's (the datasheet's gear
#: ratio and torque constant fix it far closer): the runs or the load are not what was given.
GAIN_FACTOR = 2.0


class DriveGainError(ConfigError):
    """The runs cannot give drive gains; ``swapped``: the loaded run looks like the unloaded one."""

    def __init__(self, message: str, swapped: bool = False):
        super().__init__(message)
        self.swapped = swapped


def gain_problem(gains: np.ndarray, reference: np.ndarray, joints=range(6)) -> str | None:
    """Why drive gains [N·m/A] are no drive's, or None: not finite, ≤ 0, or beyond
    :data:`GAIN_FACTOR` of the robot file's ``reference`` (names the first such joint of ``joints``,
    0-based)."""
    ratio = np.asarray(gains, dtype=float) / np.asarray(reference, dtype=float)
    for j in joints:
        g, r = gains[j], ratio[j]
        if not np.isfinite(g) or not 1 / GAIN_FACTOR <= r <= GAIN_FACTOR:
            return (f"joint {j + 1}'s gain {g:.4g} N·m/A is {r:.3g} × the robot file's {reference[j]:.4g} "
                    f"(physical: within {1 / GAIN_FACTOR:g}-{GAIN_FACTOR:g} ×)")
    return None


def _check_scale(gains: np.ndarray, reference: np.ndarray) -> None:
    """DriveGainError unless the gains' typical scale (their median ratio to the robot file's) is
    a drive's: negative when the loaded run carries less torque than the unloaded one (swapped),
    far off when the loaded run does not show the given load."""
    ratio = float(np.median(np.asarray(gains, dtype=float) / np.asarray(reference, dtype=float)))
    if not np.isfinite(ratio):
        raise DriveGainError("the runs do not determine the drive gains (no finite fit)")
    if ratio <= 0:
        raise DriveGainError(f"the drive gains come out negative ({ratio:.3g} × the robot file's): the "
                             "loaded run carries less torque than the unloaded one", swapped=True)
    if not 1 / GAIN_FACTOR <= ratio <= GAIN_FACTOR:
        raise DriveGainError(f"the drive gains come out at {ratio:.3g} × the robot file's: the loaded run "
                             "does not show the given load's torque (is the load mounted in the loaded "
                             "run only, with the mass and centre of mass given?)")


def payload_params(mass: float, com: Sequence[float], inertia_com: np.ndarray | None = None) -> np.ndarray:
    """Ten parameters (about K_6) of a payload of ``mass`` [kg] with centre of mass ``com`` [m] in K_6."""
    from urident.model.parameters import body_params

    if not mass > 0:
        raise ConfigError(f"payload mass must be positive, not {mass}")
    inertia = np.zeros((3, 3)) if inertia_com is None else np.asarray(inertia_com, dtype=float)
    return body_params(float(mass), np.asarray(com, dtype=float), inertia)


def payload_torque(spec, q, qd, qdd, payload: np.ndarray) -> np.ndarray:
    """(N, 6) torque of a payload (ten parameters about K_6) on the joints."""
    from urident.ident import features
    from urident.model import regressor_blocks

    return features.payload_torque(regressor_blocks(spec, q, qd, qdd), payload)


def estimate_drive_gains(spec, run_without, run_with, payload: np.ndarray,
                         reduced: bool = False, friction_eps: float = 0.01,
                         offset: bool = False, load_friction: bool = True) -> DriveGainEstimate:
    """Drive gains from two runs (module doc). ``run_without``/``run_with`` are ``(q, qd, qdd,
    current)`` tuples of (N, 6) arrays; ``payload`` the payload's ten parameters about K_6
    (:func:`payload_params`); ``offset``: a constant torque per joint in the arm model (a
    current-sensor offset or asymmetric friction, the same in both runs); ``load_friction``: the
    friction the known load adds, z_j·(|τ_L + τ_load| − |τ_L|) with a free coefficient per joint
    in the loaded run (harmonic drives' Coulomb friction grows with the torque they carry; left
    out, it grows with the load like a gain and biases it)."""
    from urident.model import regressor, regressor_blocks
    from urident.model.base import base_parameters

    base = base_parameters(spec, reduced)
    b = base.n_base + (6 if offset else 0) + (6 if load_friction else 0)
    wbs, currents, rhs = [], [], []
    for k, run in enumerate((run_without, run_with)):
        q, qd, qdd, current = (np.asarray(x, dtype=float) for x in run)
        wb = base.columns(regressor(spec, q, qd, qdd, friction_eps))
        if offset:
            wb = np.hstack([wb, np.tile(np.eye(6), (q.shape[0], 1))])
        if load_friction:
            extra = np.zeros((q.shape[0], 6, 6))
            if k == 1:
                from urident.ident.features import link_torque

                link = link_torque(regressor_blocks(spec, q, qd, qdd, friction_eps), spec.nominal_params)
                tau_load = payload_torque(spec, q, qd, qdd, payload)
                j = np.arange(6)
                extra[:, j, j] = np.tanh(qd / friction_eps) * (np.abs(link + tau_load) - np.abs(link))
            wb = np.hstack([wb, extra.reshape(-1, 6)])
        wbs.append(wb)
        currents.append(current)
        rhs.append(np.zeros(current.size) if k == 0
                   else -payload_torque(spec, q, qd, qdd, payload).reshape(-1))
    y = np.concatenate(rhs)

    def stacked(cur_list):
        blocks = []
        for wb, cur in zip(wbs, cur_list):
            n = cur.shape[0]
            diag = np.zeros((6 * n, 6))
            diag[np.arange(6 * n), np.tile(np.arange(6), n)] = cur.reshape(-1)
            blocks.append(np.hstack([wb, -diag]))
        return np.vstack(blocks)

    a = stacked(currents)
    scale = np.linalg.norm(a, axis=0)
    scale[scale == 0] = 1.0
    x = np.linalg.lstsq(a / scale, y, rcond=None)[0] / scale
    _check_scale(x[b:], spec.drive_gains)   # before the instruments divide by the gains
    # The measured currents are noisy regressors (errors in variables), which biases plain least
    # squares towards smaller gains. Instrumental variables fix it: the instruments are the same
    # columns with the currents predicted by the first fit, uncorrelated with the noise.
    for _ in range(2):
        predicted = []
        for k, (wb, cur) in enumerate(zip(wbs, currents)):
            tau = (wb @ x[:b]).reshape(-1, 6) - (0 if k == 0 else rhs[1].reshape(-1, 6))
            predicted.append(tau / x[b:])
        z = stacked(predicted)
        try:
            x = np.linalg.solve((z / scale).T @ (a / scale), (z / scale).T @ y) / scale
        except np.linalg.LinAlgError:
            raise DriveGainError("the runs do not determine the drive gains (singular instrumental-"
                                 "variable system: do both runs move every joint?)") from None
        _check_scale(x[b:], spec.drive_gains)
    e = a @ x - y
    dof = max(a.shape[0] - a.shape[1], 1)
    zs, as_ = z / scale, a / scale
    try:
        m = np.linalg.inv(zs.T @ as_)
    except np.linalg.LinAlgError:
        raise DriveGainError("the runs do not determine the drive gains (singular covariance)") from None
    from urident.ident.estimate import correlation_inflation

    # per run: a smooth residual (unmodelled effects) carries fewer independent samples than rows
    inflation = max(correlation_inflation(e[:currents[0].size]), correlation_inflation(e[currents[0].size:]))
    cov = m @ (zs.T @ zs) @ m.T * (e @ e / dof) / np.outer(scale, scale) * inflation
    return DriveGainEstimate(x[b:], np.sqrt(np.diag(cov))[b:], x[:b])


def effort_values(recording, spec, effort: str) -> tuple[np.ndarray, str]:
    """(N, 6) values of kind ``effort`` (``current`` [A], ``torque`` or ``compensated`` [N·m]) for
    ``recording``, and how they were obtained (``urident convert --bag-effort``)."""
    kind = torque_kind(recording)
    if effort == "current":
        if recording.metadata.get("current_from_torque"):
            full = "(compensated torque + nominal gravity)" if kind == "compensated" else "full torque"
            return recording.current, f"motor current = {full} / drive gains (the log has no current)"
        return recording.current, "the log's motor current"
    if kind == effort or (effort == "torque" and kind == "full"):
        return recording.tau, "the log's joint torque"
    full = (recording.current * spec.drive_gains if kind != "compensated"
            else recording.tau + restored_gravity(recording, spec))
    if effort == "torque":
        return full, "current x drive gains" if kind != "compensated" else \
            "compensated torque + nominal gravity"
    return full - restored_gravity(recording, spec), \
        "current x drive gains less the nominal model's gravity (and the declared payload's)"
