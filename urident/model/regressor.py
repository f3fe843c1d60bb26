"""The paper's regressor Θ(q, q̇, q̈) ∈ R^{6×78} (eq. 38), vectorised over samples.

Method: a forward recursion gives each body's angular velocity, angular acceleration and the
acceleration of its joint-frame origin (gravity folded in as a base acceleration). Each body's
wrench at its frame origin is linear in its ten parameters, ``w_i = Y_i p_i`` with Y_i (6×10).
The torque it causes at joint j ≤ i is the projection of that wrench on joint j's motion subspace
seen from K_i (``[z_j × (o_i − o_j); z_j]`` in K_i coordinates), so every block of Θ is one small
product, with no per-sample Python loop. Rotor inertia and friction add diagonal columns.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from urident.model.kinematics import AXIS_INDEX, packed_joints
from urident.model.parameters import COULOMB_OFFSET, N_PARAMS, ROTOR_OFFSET, VISCOUS_OFFSET, body_slice
from urident.model.robot import RobotSpec

try:  # compiled kernel (setup.py builds it when a C compiler is available)
    from urident.model import _regressor_kernel
except ImportError:  # pragma: no cover - exercised only where the build was skipped
    _regressor_kernel = None

DEFAULT_FRICTION_EPS = 0.01  # [rad/s] slope of tanh(q̇/ε) ≈ sign(q̇)
BACKENDS = ("auto", "c", "numpy")


PARALLEL_MIN_SAMPLES = 4096  # below this, one thread is faster than handing out work
_pool: ThreadPoolExecutor | None = None


def kernel_available() -> bool:
    return _regressor_kernel is not None


def kernel_threads() -> int:
    """Threads the compiled kernel splits large batches over (it releases the GIL): the CPU count,
    at most 4, or ``URIDENT_REGRESSOR_THREADS``."""
    value = os.environ.get("URIDENT_REGRESSOR_THREADS")
    if value:
        try:
            return max(1, int(value))
        except ValueError:
            pass
    return max(1, min(4, os.cpu_count() or 1))


def _fill_kernel(spec: RobotSpec, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
                 friction_eps: float) -> np.ndarray:
    global _pool
    n = q.shape[0]
    out = np.empty((n, 6, N_PARAMS))  # the kernel writes every entry
    geometry, axes = _kernel_geometry(spec)
    q, qd, qdd = (np.ascontiguousarray(x) for x in (q, qd, qdd))
    threads = 1 if n < PARALLEL_MIN_SAMPLES else kernel_threads()  # os.cpu_count() costs ~50 µs a call
    if threads == 1:
        _regressor_kernel.fill(out, q, qd, qdd, geometry, axes, float(friction_eps))
        return out
    if _pool is None or _pool._max_workers != threads:
        _pool = ThreadPoolExecutor(max_workers=threads, thread_name_prefix="urident-regressor")
    bounds = np.linspace(0, n, threads + 1).astype(int)
    jobs = [_pool.submit(_regressor_kernel.fill, out[a:b], q[a:b], qd[a:b], qdd[a:b], geometry, axes,
                         float(friction_eps)) for a, b in zip(bounds[:-1], bounds[1:])]
    for job in jobs:
        job.result()
    return out


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product of component-major vectors (3, ...), broadcasting the rest."""
    return np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _rotate_t(fixed_t: np.ndarray | None, axis: str, c: np.ndarray, s: np.ndarray,
              v: np.ndarray) -> np.ndarray:
    """R^T v for R = fixed · Rot_axis(q), component-major v (3, ...), c = cos q, s = sin q."""
    if fixed_t is not None:
        v = np.tensordot(fixed_t, v, axes=1)
    if axis == "z":
        return np.stack([c * v[0] + s * v[1], c * v[1] - s * v[0], v[2]])
    if axis == "y":
        return np.stack([c * v[0] - s * v[2], v[1], s * v[0] + c * v[2]])
    return np.stack([v[0], c * v[1] + s * v[2], c * v[2] - s * v[1]])


def _body_wrench_regressor(w: np.ndarray, wd: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Y (6, 10, N): force (rows 0-2) and moment (rows 3-5) about the body frame origin, linear in
    (m, mρx, mρy, mρz, A, B, C, D, E, F), from the body's angular velocity ``w``, angular
    acceleration ``wd`` and origin acceleration ``a`` (gravity included), all (3, N) in its frame:
    f = m a + (ω̇^ + ω^ω^) h and n = h × a + J ω̇ + ω × (J ω)."""
    y = np.zeros((6, 10, w.shape[1]))
    wx, wy, wz = w
    dx, dy, dz = wd
    ax, ay, az = a
    wxx, wyy, wzz, wxy, wxz, wyz = wx * wx, wy * wy, wz * wz, wx * wy, wx * wz, wy * wz
    y[0:3, 0] = a
    y[0, 1], y[0, 2], y[0, 3] = -wyy - wzz, wxy - dz, wxz + dy
    y[1, 1], y[1, 2], y[1, 3] = wxy + dz, -wxx - wzz, wyz - dx
    y[2, 1], y[2, 2], y[2, 3] = wxz - dy, wyz + dx, -wxx - wyy
    y[3, 2], y[3, 3] = az, -ay
    y[4, 1], y[4, 3] = -az, ax
    y[5, 1], y[5, 2] = ay, -ax
    y[3, 4], y[3, 5], y[3, 6] = dx, -wyz, wyz
    y[3, 7], y[3, 8], y[3, 9] = wzz - wyy, -dz - wxy, -dy + wxz
    y[4, 4], y[4, 5], y[4, 6] = wxz, dy, -wxz
    y[4, 7], y[4, 8], y[4, 9] = -dz + wxy, wxx - wzz, -dx - wyz
    y[5, 4], y[5, 5], y[5, 6] = -wxy, wxy, dz
    y[5, 7], y[5, 8], y[5, 9] = -dy - wxz, -dx + wyz, wyy - wxx
    return y


def regressor(spec: RobotSpec, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
              friction_eps: float = DEFAULT_FRICTION_EPS, backend: str = "auto") -> np.ndarray:
    """Stacked regressor (6N, 78) for (N, 6) joint positions, velocities and accelerations;
    row ``6k + j`` is joint j at sample k, so ``regressor(...) @ p == tau.reshape(-1)``."""
    return regressor_blocks(spec, q, qd, qdd, friction_eps, backend).reshape(-1, N_PARAMS)


def regressor_blocks(spec: RobotSpec, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
                     friction_eps: float = DEFAULT_FRICTION_EPS, backend: str = "auto",
                     chunk: int = 4096) -> np.ndarray:
    """The same regressor as an (N, 6, 78) array.

    ``backend``: ``"c"`` the compiled kernel (large batches split over :func:`kernel_threads`
    threads), ``"numpy"`` the vectorised implementation (computed ``chunk`` samples at a time to
    keep intermediates in cache), ``"auto"`` the kernel when built.
    """
    q, qd, qdd = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, qd, qdd))
    if not (q.shape == qd.shape == qdd.shape) or q.ndim != 2 or q.shape[1] != 6:
        raise ValueError(f"q, qd, qdd must be (N, 6) arrays, got {q.shape}, {qd.shape}, {qdd.shape}")
    if not friction_eps > 0:
        raise ValueError(f"friction_eps must be positive, got {friction_eps}")
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
    if backend == "c" and _regressor_kernel is None:
        raise RuntimeError("the compiled regressor kernel is not built (reinstall with a C compiler)")
    if backend != "numpy" and _regressor_kernel is not None:
        return _fill_kernel(spec, q, qd, qdd, friction_eps)
    out = np.zeros((q.shape[0], 6, N_PARAMS))
    for start in range(0, q.shape[0], chunk):
        stop = start + chunk
        _fill(spec, q[start:stop], qd[start:stop], qdd[start:stop], friction_eps, out[start:stop])
    return out


def _kernel_geometry(spec: RobotSpec) -> tuple[np.ndarray, bytes]:
    """The kernel's packed robot description (:func:`packed_joints`, then gravity), cached on the spec."""
    cached = spec.arrays.get("_kernel_geometry")
    if cached is None:
        joints, axes = packed_joints(spec)
        cached = spec.arrays["_kernel_geometry"] = (np.concatenate([joints, spec.gravity]).astype(float), axes)
    return cached


def _fill(spec: RobotSpec, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, friction_eps: float,
          out: np.ndarray) -> None:
    n = q.shape[0]
    q_t, qd_t, qdd_t = q.T, qd.T, qdd.T
    w = np.zeros((3, n))
    wd = np.zeros((3, n))
    a = np.repeat(-spec.gravity[:, None], n, axis=1)  # gravity as a base acceleration
    # For every ancestor joint k ≤ i: z_k × (o_i − o_k) (lin) and z_k (ang), in K_i, shape (3, i+1, N).
    lin = np.zeros((3, 0, n))
    ang = np.zeros((3, 0, n))
    for i, joint in enumerate(spec.joints):
        fixed_t = None if np.array_equal(joint.rotation, np.eye(3)) else joint.rotation.T
        c, s = np.cos(q_t[i]), np.sin(q_t[i])
        p = joint.xyz[:, None]
        axis = AXIS_INDEX[joint.axis]
        # The origin's acceleration uses the parent's ω and ω̇.
        a = _rotate_t(fixed_t, joint.axis, c, s, a + _cross(wd, p) + _cross(w, _cross(w, p)))
        w = _rotate_t(fixed_t, joint.axis, c, s, w)
        wd = _rotate_t(fixed_t, joint.axis, c, s, wd)
        unit = np.zeros((3, 1))
        unit[axis] = 1.0
        wd += _cross(w, unit) * qd_t[i]  # ω_parent × q̇ z
        wd[axis] += qdd_t[i]
        w[axis] += qd_t[i]
        if i:
            lin = _rotate_t(fixed_t, joint.axis, c, s, lin + _cross(ang, p[:, :, None]))
            ang = _rotate_t(fixed_t, joint.axis, c, s, ang)
        lin = np.concatenate([lin, np.zeros((3, 1, n))], axis=1)
        ang = np.concatenate([ang, np.broadcast_to(unit[:, :, None], (3, 1, n))], axis=1)
        y = np.ascontiguousarray(_body_wrench_regressor(w, wd, a).transpose(2, 0, 1))  # (N, 6, 10)
        motion = np.ascontiguousarray(np.concatenate([lin, ang]).transpose(2, 1, 0))  # (N, i+1, 6)
        # τ_k gets v_k · f_i + u_k · n_i from body i, for every joint k ≤ i.
        out[:, : i + 1, body_slice(i)] = motion @ y
    joints = np.arange(6)
    out[:, joints, ROTOR_OFFSET + joints] = qdd
    out[:, joints, VISCOUS_OFFSET + joints] = qd
    out[:, joints, COULOMB_OFFSET + joints] = np.tanh(qd / friction_eps)


def perturbed_states(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, h: float
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """States (19, N, 6): the point, then q + h·e_j, q̇ + h·e_j (forward differences) and q̈ + e_j
    (Θ is linear in q̈), each j = 1..6 in turn."""
    eye, zero, point = np.eye(6), np.zeros((6, 6)), np.zeros((1, 6))
    dq_ = np.concatenate([point, h * eye, zero, zero])
    dqd = np.concatenate([point, zero, h * eye, zero])
    dqdd = np.concatenate([point, zero, zero, eye])
    return (q[None] + dq_[:, None], qd[None] + dqd[:, None], qdd[None] + dqdd[:, None])


def weighted_state_derivatives(spec: RobotSpec, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
                               weights: np.ndarray, h: float, friction_eps: float = DEFAULT_FRICTION_EPS,
                               backend: str = "auto") -> np.ndarray:
    """(18, N): the derivatives of each sample's ``s_k = Σ_{j,p} weights[k, j, p] Θ(q_k, q̇_k, q̈_k)[j, p]``
    in its q_1..6, q̇_1..6 and q̈_1..6, for (N, 6) states and (N, 6, 78) weights.

    The compiled kernel differentiates exactly, in reverse mode: one pass out along the chain,
    one back carrying the adjoints of each body's velocity, acceleration and motion subspaces
    (about the cost of three regressor rows, not 19 regressors). The numpy path forms the 19
    regressors of forward steps ``h`` in q and q̇ and unit steps in q̈ (:func:`perturbed_states`)
    and differences the sums: exact in q̈, within about 1e-7 relative of the kernel in q and q̇."""
    q, qd, qdd = (np.ascontiguousarray(np.atleast_2d(x), dtype=float) for x in (q, qd, qdd))
    weights = np.ascontiguousarray(weights, dtype=float)
    n = q.shape[0]
    if not (q.shape == qd.shape == qdd.shape == (n, 6)) or weights.shape != (n, 6, N_PARAMS):
        raise ValueError(f"q, qd, qdd must be (N, 6) and weights (N, 6, {N_PARAMS}), got {q.shape}, {qd.shape}, "
                         f"{qdd.shape} and {weights.shape}")
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
    if backend != "numpy" and _regressor_kernel is not None:
        out = np.empty((18, n))  # the kernel writes every entry
        geometry, axes = _kernel_geometry(spec)
        _regressor_kernel.weighted_derivatives(out, q, qd, qdd, weights, geometry, axes, float(friction_eps))
        return out
    states = perturbed_states(q, qd, qdd, h)
    blocks = regressor_blocks(spec, *(s.reshape(-1, 6) for s in states), friction_eps=friction_eps,
                              backend=backend).reshape(len(states[0]), n, 6, N_PARAMS)
    values = np.einsum("kjp,skjp->sk", weights, blocks)
    return np.concatenate([(values[1:13] - values[0]) / h, values[13:19] - values[0]])


def joint_torques(spec: RobotSpec, params: np.ndarray, q: np.ndarray, qd: np.ndarray,
                  qdd: np.ndarray, friction_eps: float = DEFAULT_FRICTION_EPS) -> np.ndarray:
    """(N, 6) joint torques Θ(q, q̇, q̈)·p [N m] for a 78-vector ``params``."""
    return regressor_blocks(spec, q, qd, qdd, friction_eps) @ np.asarray(params, dtype=float)
