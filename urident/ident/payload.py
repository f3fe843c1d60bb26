"""A payload's ten inertial parameters estimated with the arm fixed, and its torque on the joints.
The :class:`~urident.model.payload.Payload` type, its flange frame and the map L to the last
body's parameters are :mod:`urident.model.payload`'s.

Estimation (:func:`estimate_payload`): the arm's parameters fixed, the residual
τ_measured − τ_arm = Y_6 L φ_F is linear in φ_F (Y_6: the regressor columns of body 6). Which of
the ten the data excite is decided by a pivoted QR of the column-normalised, joint-weighted
regressor (a column within 1e-3 of the span of the others carries nothing of its own) and then by
each parameter's standard deviation (inflated for the residual's autocorrelation:
:func:`urident.ident.estimate.joint_correlation_inflation`, per joint) against a physical tolerance (:data:`TOLERANCES`); the rest
are fixed (first moments at 0, inertia at a point mass's) and reported as not identifiable. The
physically consistent estimate solves the same least squares over all ten with the payload's
pseudo-inertia ⪰ 0, m in ``mass_range``, a weak prior (the arm's λ) towards the least-squares
values on the identifiable parameters and a strong one on the fixed ones (they move only where
the constraints need it).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from urident.ident.estimate import joint_correlation_inflation
from urident.model.parameters import inertia_matrix
from urident.model.payload import PAYLOAD_FIELDS, Payload, PayloadError, flange_map, from_flange_vector

#: A parameter whose σ exceeds its tolerance is reported as not identifiable: mass 5 % (at least
#: 0.02 kg), first moments 5 mm × mass, inertias 15 % of the smallest principal inertia about the
#: centre of mass at INERTIA_SIGMAS σ (≥ 1e-5 kg·m²), so an inertia reported is within 15 % on
#: every principal axis with ~95 % confidence.
TOLERANCES = {"mass_rel": 0.05, "mass_abs": 0.02, "com_m": 0.005, "inertia_rel": 0.15, "inertia_abs": 1e-5}
INERTIA_SIGMAS = 2.0
#: Structural rank threshold on the column-normalised regressor (sine to the span of the others).
RANK_TOL = 1e-3
#: |q| range [rad] below which a wrist joint counts as not moving.
MIN_WRIST_RANGE_RAD = 0.02
#: A tare is the same motion as a loaded run: over the selected rows, timed from each selection's
#: first row, the spans agree within 5 % and every joint within 0.05 rad at every sample (the
#: real UR10e load/unload pair, aligned rows: 0.025 rad; one 10 ms row off at 1 rad/s: +0.01 rad).
TARE_POSITION_TOL_RAD = 0.05
TARE_SPAN_TOL = 0.05
#: A tare is laid over a loaded log at the time offset (within ± this many sample periods, in
#: quarter periods) that matches their joint positions best: logs started by hand are not in step.
TARE_SHIFT_PERIODS = 3


def payload_regressor(spec, blocks: np.ndarray) -> np.ndarray:
    """(N, 6, 10) columns of φ_F from the (N, 6, 78) regressor: a payload's joint torque is
    ``payload_regressor(spec, blocks) @ payload.flange_vector`` (module doc: Y_6 L)."""
    from urident.ident.features import tool_body_regressor

    return tool_body_regressor(blocks) @ flange_map(spec)


_SCALE_CACHE: dict[tuple, np.ndarray] = {}
REFERENCE_SAMPLES = 2000


def payload_reference_scales(spec) -> np.ndarray:
    """(10,) RMS (per sample, summed over joints) of each payload column over random states, the
    reference that makes the columns' units (kg, kg·m, kg·m²) comparable in a condition number
    (as :func:`urident.excitation.criteria.reference_scales` for the arm)."""
    from urident.model import regressor_blocks
    from urident.model.base import random_states

    key = (spec.name, str(spec.source), spec.tool_xyz.tobytes(), spec.tool_rotation.tobytes())
    if key not in _SCALE_CACHE:
        states = random_states(spec, REFERENCE_SAMPLES, np.random.default_rng(0))
        a = payload_regressor(spec, regressor_blocks(spec, *states))
        _SCALE_CACHE[key] = np.sqrt(np.sum(a ** 2, axis=(0, 1)) / REFERENCE_SAMPLES)
    return _SCALE_CACHE[key].copy()


def payload_condition(spec, q, qd, qdd) -> float:
    """cond of the payload columns (reference-scaled, :func:`payload_reference_scales`) stacked
    over the samples (N, 6): how well the motion determines all ten payload parameters with the
    arm fixed (``excite --for-payload`` minimises it)."""
    from urident.model import regressor_blocks

    a = payload_regressor(spec, regressor_blocks(spec, q, qd, qdd)).reshape(-1, 10)
    sv = np.linalg.svd(a / payload_reference_scales(spec), compute_uv=False)
    return float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")


def payload_torque(spec, payload: Payload, q, qd, qdd) -> np.ndarray:
    """(N, 6) joint torque of ``payload`` at states (q, q̇, q̈)."""
    from urident.ident.torque import payload_torque as body_torque

    return body_torque(spec, q, qd, qdd, payload.body_params(spec))


def without_payload(spec, payload: Payload, data):
    """Prepared ``data`` with the payload's torque removed from the measured torque (the arm
    alone; ``identify --payload``, ``gap --payload``)."""
    from dataclasses import replace

    check_robot(payload, spec)
    return replace(data, tau=data.tau - payload_torque(spec, payload, data.q, data.qd, data.qdd))


def check_robot(payload: Payload, spec, where: str = "payload") -> None:
    if payload.robot != spec.name:
        raise PayloadError(f"{where}: payload identified on robot {payload.robot!r}, not {spec.name!r}")


def check_wrist_motion(q: np.ndarray, where: str = "logs") -> None:
    """PayloadError when none of the wrist joints (4-6) moves: the payload is then not excited."""
    q = np.asarray(q, dtype=float)
    span = q[:, 3:].max(axis=0) - q[:, 3:].min(axis=0) if len(q) else np.zeros(3)
    if not np.any(span > MIN_WRIST_RANGE_RAD):
        raise PayloadError(f"{where}: the wrist joints 4-6 do not move (ranges "
                           f"{', '.join(f'{s:.3g}' for s in span)} rad): a payload cannot be identified")


def check_same_motion(loaded, tare) -> None:
    """PayloadError (one line) unless every tare run matches one of the loaded runs and every
    loaded run has a tare (module constants ``TARE_*``): the tare is subtracted sample by sample.
    ``loaded``, ``tare``: sequences of (label, t (N,), q (N, 6))."""
    for label, tu, qu in tare:
        closest = _closest_motion(loaded, tu, qu)
        if closest is not None:
            _, text, other = closest
            raise PayloadError(f"{label}: not the same motion as the loaded log {other}: {text}: a tare "
                               f"must run the same trajectory over the same rows (--unloaded-rows)")
    for label, tl, ql in loaded:
        closest = _closest_motion(tare, tl, ql, loaded_first=False)
        if closest is not None:
            _, text, other = closest
            raise PayloadError(f"{label}: no tare runs its motion (closest, {other}: {text}): give each "
                               f"loaded log an --unloaded log of the same trajectory, or leave it out")


def _closest_motion(candidates, t, q, loaded_first: bool = True):
    """None when (t, q) is the motion of one of ``candidates``, else (badness, reason, label) of the
    closest; ``loaded_first``: the candidates are the loaded runs (else the tares)."""
    closest = None
    for other, tc, qc in candidates:
        tc, qc, tx, qx = np.asarray(tc, float), np.asarray(qc, float), np.asarray(t, float), np.asarray(q, float)
        problem = _motion_difference(tc, qc, tx, qx) if loaded_first else _motion_difference(tx, qx, tc, qc)
        if problem is None:
            return None
        closest = closest if closest is not None and closest[0] <= problem[0] else (*problem, other)
    return closest


def _motion_difference(tl, ql, tu, qu):
    """None when (tu, qu) is the motion (tl, ql), else (badness, reason)."""
    span_l, span_u = tl[-1] - tl[0], tu[-1] - tu[0]
    if abs(span_u - span_l) > TARE_SPAN_TOL * max(span_l, span_u, 1e-9):
        return np.inf, (f"its rows span {span_u:.2f} s, the loaded log's {span_l:.2f} s "
                        f"(tolerance {100 * TARE_SPAN_TOL:g} %)")
    dl, du = tl - tl[0], tu - tu[0]
    keep = dl <= du[-1]
    q_at = np.column_stack([np.interp(dl[keep], du, qu[:, j]) for j in range(6)])
    diff = np.abs(ql[keep] - q_at)
    k, j = np.unravel_index(int(np.argmax(diff)), diff.shape)
    if diff[k, j] <= TARE_POSITION_TOL_RAD:
        return None
    return float(diff[k, j]), (f"joint {j + 1} differs by {diff[k, j]:.3f} rad at {dl[keep][k]:.2f} s "
                               f"into the rows (tolerance {TARE_POSITION_TOL_RAD:g} rad)")


def since_first_row(prediction, recordings):
    """``prediction``'s data with each sample's time counted from its log's first row, the time
    on which :func:`estimate_payload` lays a tare over a loaded run (as :func:`check_same_motion`)."""
    data = prediction.data
    t0 = np.array([float(recordings[k].t[0]) for k, _ in prediction.recording_pieces()])
    return replace(data, t=data.t - t0[data.segment])


def _tare_shift(tl, ql, tu, qu) -> float | None:
    """The offset s [s] at which the tare (tu, qu) follows (tl, ql) best, q_u(t + s) ≈ q_l(t), over
    ± :data:`TARE_SHIFT_PERIODS`; None when no offset overlaps half the loaded piece."""
    period = float(np.median(np.diff(tl))) if len(tl) > 1 else 0.0
    best, best_cost = None, np.inf
    for s in np.arange(-4 * TARE_SHIFT_PERIODS, 4 * TARE_SHIFT_PERIODS + 1) * period / 4:
        inside = (tl + s >= tu[0]) & (tl + s <= tu[-1])
        if inside.sum() < max(len(tl) // 2, 2):
            continue
        cost = sum(float(np.mean((np.interp(tl[inside] + s, tu, qu[:, j]) - ql[inside, j]) ** 2))
                   for j in range(6))
        if cost < best_cost:
            best, best_cost = float(s), cost
    return best


def tare_at(data, unloaded, residual_u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(N, 6) the mean over the tare runs of their residual ``residual_u`` at each loaded sample's
    point of the motion, (N,) how many tares cover it, and (N,) how many loaded pieces those tares
    cover on average (a tare shared by several loaded runs correlates their errors). A tare piece
    covers a loaded piece when, at its best time offset (:func:`_tare_shift`; times from each
    log's first row, :func:`since_first_row`), every joint is within :data:`TARE_POSITION_TOL_RAD`."""
    loaded_pieces = [np.flatnonzero(data.segment == s) for s in np.unique(data.segment)]
    tare_pieces = [np.flatnonzero(unloaded.segment == s) for s in np.unique(unloaded.segment)]
    matches = []   # (loaded piece, tare piece, loaded samples covered, tare residual there)
    for a, i in enumerate(loaded_pieces):
        tl, ql = data.t[i], data.q[i]
        for b, j in enumerate(tare_pieces):
            tu, qu = unloaded.t[j], unloaded.q[j]
            shift = _tare_shift(tl, ql, tu, qu)
            if shift is None:
                continue
            inside = (tl + shift >= tu[0]) & (tl + shift <= tu[-1])
            at = lambda x: np.column_stack([np.interp(tl[inside] + shift, tu, x[:, c]) for c in range(6)])  # noqa: E731
            if np.max(np.abs(at(qu) - ql[inside])) <= TARE_POSITION_TOL_RAD:
                matches.append((a, b, i[inside], at(residual_u[j])))
    uses = np.bincount([b for _, b, _, _ in matches], minlength=len(tare_pieces))
    total, count, shared = np.zeros_like(data.tau), np.zeros(len(data)), np.zeros(len(data))
    for _, b, rows, r in matches:
        total[rows] += r
        count[rows] += 1
        shared[rows] += uses[b]
    covered = np.maximum(count, 1)
    return total / covered[:, None], count, shared / covered


@dataclass(frozen=True)
class PayloadEstimate:
    ols: Payload
    consistent: Payload
    train_rms_arm: np.ndarray        # (6,) residual RMS of the arm alone [N·m]
    train_rms: np.ndarray            # (6,) with the consistent payload
    train_e_n_arm: float
    train_e_n: float
    n_samples: int


def _tolerances(phi: np.ndarray) -> np.ndarray:
    m = max(abs(phi[0]), 0.01)
    c = phi[1:4] / m
    # about the centre of mass: the flange-origin inertia's m·c² part is the first moments' business
    ic = inertia_matrix(phi[4:10], "flange") - m * (c @ c * np.eye(3) - np.outer(c, c))
    smallest = max(float(np.linalg.eigvalsh(ic)[0]), 0.0)
    tol = np.empty(10)
    tol[0] = max(TOLERANCES["mass_rel"] * m, TOLERANCES["mass_abs"])
    tol[1:4] = TOLERANCES["com_m"] * m
    relative = TOLERANCES["inertia_rel"] * smallest / INERTIA_SIGMAS if smallest > 0 else 0.0
    tol[4:10] = max(relative, TOLERANCES["inertia_abs"])
    return tol


def _fixed_values(phi: np.ndarray, free: np.ndarray) -> np.ndarray:
    """Values for the fixed parameters: first moments 0, inertias those of a point mass."""
    out = phi.copy()
    out[1:4] = np.where(free[1:4], phi[1:4], 0.0)
    m = max(phi[0], 1e-6)
    c = out[1:4] / m
    jp = m * (c @ c * np.eye(3) - np.outer(c, c))
    point = np.r_[jp[0, 0], jp[1, 1], jp[2, 2], jp[1, 2], jp[0, 2], jp[0, 1]]
    out[4:10] = np.where(free[4:10], phi[4:10], point)
    return out


def _structural(a: np.ndarray) -> np.ndarray:
    """Columns of ``a`` each with a component of its own (pivoted QR on unit columns)."""
    import scipy.linalg

    norms = np.linalg.norm(a, axis=0)
    free = norms > 0
    an = a[:, free] / norms[free]
    _, r, piv = scipy.linalg.qr(an, mode="economic", pivoting=True)
    keep = np.abs(np.diag(r)) > RANK_TOL
    idx = np.flatnonzero(free)[piv[keep]]
    out = np.zeros(a.shape[1], dtype=bool)
    out[idx] = True
    return out


def _ls(a: np.ndarray, y: np.ndarray, free: np.ndarray, fixed: np.ndarray):
    """Least squares over the ``free`` columns with the others at ``fixed``: (φ, σ). σ from the
    sandwich with each joint's residual at its long-run variance (variance times its own AR(1)
    factor, :func:`joint_correlation_inflation`): the joints' residuals differ in smoothness by
    10x, and one factor for all would be the smoothest joint's."""
    rhs = y - a[:, ~free] @ fixed[~free]
    af = a[:, free]
    scale = np.linalg.norm(af, axis=0)
    an = af / scale
    x, *_ = np.linalg.lstsq(an, rhs, rcond=None)
    x /= scale
    e = af @ x - rhs
    dof = max(len(y) - af.shape[1], 1)
    ej = e.reshape(-1, 6)
    long_run = np.sum(ej ** 2, axis=0) / (dof / 6) * joint_correlation_inflation(e)
    bread = np.linalg.pinv(an.T @ an)
    meat = np.einsum("kjp,j,kjq->pq", an.reshape(-1, 6, an.shape[1]), long_run, an.reshape(-1, 6, an.shape[1]))
    cov = bread @ meat @ bread / np.outer(scale, scale)
    phi = fixed.copy()
    phi[free] = x
    sigma = np.full(10, np.nan)
    sigma[free] = np.sqrt(np.clip(np.diag(cov), 0, None))
    return phi, sigma


#: Weight of the prior on the fixed (not identifiable) parameters in the consistent estimate, per
#: tolerance²: 100× the data's curvature there at most (σ > tolerance), so they stay at their
#: least-squares values to ~0.1 tolerance unless the constraints move them.
FIXED_WEIGHT = 1e2


def _consistent(a: np.ndarray, y: np.ndarray, prior: np.ndarray, free: np.ndarray, mass_range,
                noise_var: float, regularisation: float) -> np.ndarray:
    import cvxpy as cp

    from urident.ident.estimate_consistent import ConsistentSolveError
    from urident.ident.estimate_ols import reduce_ls

    col = np.linalg.norm(a, axis=0)
    col[col == 0] = 1.0
    r_, z = reduce_ls(a / col, y)
    s = np.maximum(np.abs(prior), 1e-3)
    s[0] = max(abs(prior[0]), 0.1)
    s[1:4] = np.maximum(s[1:4], 1e-3 * s[0])
    weight = np.where(free, regularisation / s ** 2, FIXED_WEIGHT / _tolerances(prior) ** 2)
    phi = cp.Variable(10)
    objective = (cp.sum_squares(r_ @ cp.multiply(col, phi) - z) / noise_var
                 + cp.sum(cp.multiply(weight, cp.square(phi - prior))))
    m, hx, hy, hz, jxx, jyy, jzz, jyz, jxz, jxy = (phi[k] for k in range(10))
    pm = cp.Variable((4, 4), PSD=True)
    cons = [pm[0, 0] == (-jxx + jyy + jzz) / 2, pm[1, 1] == (jxx - jyy + jzz) / 2,
            pm[2, 2] == (jxx + jyy - jzz) / 2, pm[0, 1] == -jxy, pm[0, 2] == -jxz, pm[1, 2] == -jyz,
            pm[0, 3] == hx, pm[1, 3] == hy, pm[2, 3] == hz, pm[3, 3] == m]
    low, high = mass_range if mass_range is not None else (1e-3, None)
    cons.append(m >= max(low, 1e-6))
    if high is not None:
        cons.append(m <= high)
    problem = cp.Problem(cp.Minimize(objective), cons)
    import warnings

    try:
        with warnings.catch_warnings():   # 'optimal_inaccurate' (a point mass is on the cone's edge) is accepted
            warnings.simplefilter("ignore", UserWarning)
            problem.solve(solver=cp.CLARABEL)
    except cp.error.SolverError as exc:
        raise ConsistentSolveError(f"consistent payload estimation: solver failed ({exc})") from None
    if problem.status not in ("optimal", "optimal_inaccurate") or phi.value is None:
        raise ConsistentSolveError(f"consistent payload estimation: solver status {problem.status}")
    return np.asarray(phi.value, dtype=float)


#: Fits of the payload, each with the side effects of the previous one's torque as columns.
INDUCED_PASSES = 3


def _induced(data, link: np.ndarray, tau_p: np.ndarray) -> np.ndarray:
    """(6N, 12) columns of what a payload's torque ``tau_p`` (N, 6) changes besides itself, one
    free coefficient per joint: the load-dependent friction it adds, z_j·(|τ_L + τ_p| − |τ_L|)
    (τ_L: the arm's nominal link torque, z the Coulomb state; the arm model's own load-friction
    term sees τ_L only), and the current delay's share, dτ_p/dt (the measured current lags)."""
    from urident.model.regressor import DEFAULT_FRICTION_EPS

    n = len(data)
    joints = np.arange(6)
    z = np.tanh(data.qd / DEFAULT_FRICTION_EPS)
    rate = np.zeros_like(tau_p)
    for seg in np.unique(data.segment):
        k = np.flatnonzero(data.segment == seg)
        if len(k) > 2:
            rate[k] = np.gradient(tau_p[k], data.t[k], axis=0)
    out = np.zeros((n, 6, 12))
    out[:, joints, joints] = z * (np.abs(link + tau_p) - np.abs(link))
    out[:, joints, 6 + joints] = rate
    return out.reshape(-1, 12)


def _select(a_fit: np.ndarray, y_fit: np.ndarray, nuisance: np.ndarray | None, n_rows: int,
            inertia: bool = True, sigma_scale: float = 1.0):
    """Per-joint weights from a first fit, then least squares with the nuisance columns projected
    out, dropping the worst-determined parameter until every one left is within its tolerance
    (``inertia`` False: the six inertias fixed from the start): (φ, σ, free, weights, weighted and
    projected a, y)."""
    from urident.ident.estimate import joint_weights, row_weights

    # per-joint weights from a first fit: joints differ in noise and model error by 10x
    a0, y0 = (a_fit, y_fit) if nuisance is None else _project_out(nuisance, a_fit, y_fit)
    free = _structural(a0)
    if not free[0]:
        raise PayloadError("the logs do not excite the payload mass (no gravity or acceleration "
                           "torque of a tool mass reaches the joints)")
    phi, _ = _ls(a0, y0, free, np.zeros(10))
    # weights 1/(long-run std) per joint: a smooth residual carries less information per sample
    weights = joint_weights(a0, y0, phi) / np.sqrt(joint_correlation_inflation(a0 @ phi - y0))
    rw = row_weights(weights, n_rows)
    aw, yw = a_fit * rw[:, None], y_fit * rw
    if nuisance is not None:
        aw, yw = _project_out(nuisance * rw[:, None], aw, yw)
    free = _structural(aw)
    if not inertia:
        free[4:10] = False
    phi = np.zeros(10)
    for _ in range(20):  # drop the worst-determined parameter until all are within tolerance
        for _ in range(3):   # fixed inertias follow the estimated mass and centre of mass
            phi, sigma = _ls(aw, yw, free, _fixed_values(phi, free))
        sigma = sigma * sigma_scale
        ratio = np.where(free, sigma / _tolerances(phi), 0.0)
        ratio[0] = 0.0 if sigma[0] <= _tolerances(phi)[0] else ratio[0]
        worst = int(np.argmax(ratio))
        if ratio[worst] <= 1.0:
            break
        if worst == 0:
            raise PayloadError(f"the logs do not determine the payload mass (σ {sigma[0]:.3g} kg "
                               f"for {phi[0]:.3g} kg)")
        free[worst] = False
    return phi, sigma, free, weights, aw, yw


def _friction_columns(data) -> np.ndarray:
    """(N·6, 18) each joint's viscous, Coulomb and constant torque: what may differ between a
    loaded run and its tare besides the tool (the joints' temperature, the current offsets)."""
    from urident.model.regressor import DEFAULT_FRICTION_EPS

    n = len(data)
    joints = np.arange(6)
    friction = np.zeros((n, 6, 18))
    friction[:, joints, joints] = data.qd
    friction[:, joints, 6 + joints] = np.tanh(data.qd / DEFAULT_FRICTION_EPS)
    friction[:, joints, 12 + joints] = 1.0
    return friction.reshape(-1, 18)


def _project_out(n: np.ndarray, *arrays: np.ndarray) -> list[np.ndarray]:
    """Each array minus its least-squares fit on the columns of ``n`` (Frisch-Waugh: least squares
    on the results gives the payload of the joint fit with the nuisance columns free)."""
    scale = np.linalg.norm(n, axis=0)
    keep = scale > 0
    u, sv, _ = np.linalg.svd(n[:, keep] / scale[keep], full_matrices=False)
    u = u[:, sv > 1e-10 * sv[0]]
    return [x - u @ (u.T @ x) for x in arrays]


def estimate_payload(params, spec, data, mass_range=None, regularisation: float | None = None,
                     unloaded=None) -> PayloadEstimate:
    """The payload from prepared data ``data`` (:class:`urident.ident.Prepared`, torques from the
    drive gains chosen) with the arm's ``params`` (:class:`IdentifiedModel`) fixed (module doc).

    ``unloaded``: prepared runs of the same motion without the tool (a tare), times from each
    log's first row (:func:`since_first_row`). The fit is then on the difference, sample by
    sample, of the loaded run's residual and the tares' mean residual at the same point of the
    motion (:func:`tare_at`): every error the arm model makes on that motion (its last body's
    parameters, which add to the payload's exactly, friction forms it lacks, the joints'
    elasticity, a wrong rotor inertia) is in both and cancels, and the difference is sensor noise;
    each joint's viscous, Coulomb and constant torque stay free (temperature and offsets may
    differ between the runs). Loaded samples no tare covers are left out. Without a tare the inertia is
    never reported identifiable: the arm's own last-body inertia error, which no σ sees, is of the
    order of a tool's (0.03 kg·m² on the simulated UR10e, README); its columns are then fit as
    nuisance (so that error does not bias the mass and centre of mass) and the inertia reported is
    a point mass's."""
    from urident.ident.design import nominal_link_torque
    from urident.ident.estimate_consistent import DEFAULT_REGULARISATION
    from urident.ident.identify import predict_prepared
    from urident.ident.metrics import error_metrics
    from urident.model import regressor_blocks

    if mass_range is not None:
        low, high = mass_range
        if not (0 < low < high):
            raise PayloadError(f"mass range must be 0 < low < high, not {low:g}..{high:g} kg")
    check_wrist_motion(data.q)
    residual = data.tau - predict_prepared(params, spec, data)
    blocks = regressor_blocks(spec, data.q, data.qd, data.qdd)
    a = payload_regressor(spec, blocks).reshape(-1, 10)
    y = residual.reshape(-1)
    n = len(data)
    if 6 * n <= 20:
        raise PayloadError(f"{n} samples are too few to identify a payload")
    rows, a_fit, y_fit, nuisance, tared, sigma_scale = slice(None), a, y, None, 0, 1.0
    if unloaded is not None:
        check_wrist_motion(unloaded.q, "unloaded logs")
        tare, count, shared = tare_at(data, unloaded, unloaded.tau - predict_prepared(params, spec, unloaded))
        keep = count > 0
        tared = int(keep.sum())
        if 6 * tared <= 20:
            raise PayloadError("no loaded sample has a tare of the same motion (--unloaded: the same "
                               "trajectory, joints within "
                               f"{TARE_POSITION_TOL_RAD:g} rad)")
        # noise of a difference: the loaded run's plus the mean of `count` tares', whose share is
        # common to the `shared` loaded runs that use them; the residual shows each row's own
        # variance (1 + 1/count), the estimate's is as if (1 + shared/count): σ scaled by the ratio
        c, sh = count[keep], shared[keep]
        w = np.repeat(1.0 / np.sqrt(1.0 + sh / c), 6)
        sigma_scale = float(np.sqrt(np.mean((1.0 + sh / c) / (1.0 + 1.0 / c))))
        rows = np.repeat(keep, 6)
        a_fit = a[rows] * w[:, None]
        y_fit = (residual - tare)[keep].reshape(-1) * w
        nuisance = _friction_columns(data.select(keep)) * w[:, None]
        if not np.max(np.abs(y_fit)) > 1e-9 * max(float(np.max(np.abs(residual))), 1e-300):
            raise PayloadError("the tare runs' torques equal the loaded runs' (nothing between them to "
                               "identify): is the tare a run without the tool, and not the loaded log itself?")
    n_rows = len(y_fit) // 6
    link = nominal_link_torque(spec, blocks)
    phi = None
    for _ in range(INDUCED_PASSES):   # the payload's side effects follow its estimate
        extra = None if phi is None else _induced(data, link, (a @ phi).reshape(-1, 6))[rows]
        if extra is not None and unloaded is not None:
            extra = extra * w[:, None]
        # without a tare the inertia columns stay in the fit (they absorb the arm's own last-body
        # inertia error, which would bias the mass and centre of mass) but are never reported
        own = None if unloaded is not None else a[:, 4:10]
        parts = [x for x in (nuisance, extra, own) if x is not None]
        phi, sigma, free, weights, aw, yw = _select(a_fit, y_fit, np.hstack(parts) if parts else None, n_rows,
                                                    inertia=unloaded is not None, sigma_scale=sigma_scale)
    ew = aw @ phi - yw
    noise_var = max(float(ew @ ew) / max(len(yw) - int(free.sum()), 1), 1e-300)
    identifiable = tuple(name for name, f in zip(PAYLOAD_FIELDS, free) if f)
    info = {"weights": [float(v) for v in weights], "unloaded_samples": 0 if unloaded is None else len(unloaded),
            "tared_samples": tared, "tare_sigma_scale": sigma_scale}
    ols = from_flange_vector(spec.name, phi, sigma=_sigma_dict(phi, sigma),
                             identifiable=identifiable, method="ols", info=info)
    reg = DEFAULT_REGULARISATION if regularisation is None else regularisation
    phi_c = _consistent(aw, yw, phi, free, mass_range, noise_var, reg)
    bound = mass_bound(phi_c[0], mass_range)
    if bound is not None:    # on the bound, not the solver's 1e-8 beside it (a bound at the rated payload)
        phi_c[0] = bound
    phi_c[4:10] += _psd_repair(phi_c)
    problem = spec.rated_payload_problem(float(phi_c[0])) or spec.tool_com_problem(phi_c[1:4] / phi_c[0])
    if problem:    # no file the arm's commands would refuse to read
        raise PayloadError(f"the estimated tool is not one the arm can carry: {problem} (are the arm's "
                           "parameters and drive gains right for these logs?)")
    cons_info = info if bound is None else {**info, "mass_bound_kg": bound}
    cons = from_flange_vector(spec.name, phi_c, sigma=_sigma_dict(phi_c, sigma),
                              identifiable=tuple(n for n in identifiable if bound is None or n != "m"),
                              method="consistent", info=cons_info)
    e_arm, rms_arm = error_metrics(residual)
    e_pl, rms_pl = error_metrics(residual - (a @ phi_c).reshape(-1, 6))
    return PayloadEstimate(ols, cons, rms_arm, rms_pl, e_arm, e_pl, n)


#: The consistent mass counts as on a ``mass_range`` bound within this relative distance (the
#: solver's tolerance is ~1e-8, 1e-4 seen when it ends "inaccurate"): the bound, not the data, sets it.
BOUND_TOL = 1e-3


def mass_bound(mass: float, mass_range) -> float | None:
    """The bound of ``mass_range`` the mass sits on (an active constraint), or None."""
    if mass_range is None:
        return None
    for bound in mass_range:
        if abs(mass - bound) <= BOUND_TOL * bound:
            return float(bound)
    return None


def _psd_repair(phi: np.ndarray) -> np.ndarray:
    """Change of the flange inertia entries that lifts the solver's negative eigenvalues of the
    second-moment matrix about the centre of mass, Σ = tr(I_c)/2·1 − I_c, to zero (the SDP's
    tolerance): I_c = tr(Σ)·1 − Σ is then ⪰ 0 and within the triangle inequality, as the payload
    file's reader requires."""
    m = phi[0]
    c = phi[1:4] / m
    ic = inertia_matrix(phi[4:10], "flange") - m * (c @ c * np.eye(3) - np.outer(c, c))
    w, v = np.linalg.eigh(0.5 * np.trace(ic) * np.eye(3) - ic)
    second = (v * np.clip(w, 0, None)) @ v.T
    d = np.trace(second) * np.eye(3) - second - ic
    return np.array([d[0, 0], d[1, 1], d[2, 2], d[1, 2], d[0, 2], d[0, 1]])


def _sigma_dict(phi: np.ndarray, sigma: np.ndarray) -> dict:
    """σ of mass, centre of mass and inertia about it (first order; NaN where fixed)."""
    m = phi[0]
    s_m = sigma[0]
    s_c = np.sqrt((sigma[1:4] / m) ** 2 + (phi[1:4] * s_m / m ** 2) ** 2)
    s_j = inertia_matrix(sigma[4:10], "flange")
    return {"mass_kg": float(s_m), "com_m": [float(v) for v in s_c],
            "inertia_kg_m2": [[float(v) for v in row] for row in s_j]}
