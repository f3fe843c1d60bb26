"""Vectorised capsule distances (self-collision and floor/mount plane) in numpy, and the same
distances from Pinocchio/coal for the final dense verification.

Pairs are those of :func:`urident.model.pinocchio_model.collision_link_pairs` (capsule × capsule)
and :func:`floor_checked_links` (capsule × floor plane ``z = floor_height_m``), in that order.

Required distance per pair. The robot files' capsules are conservative, so some non-adjacent links
are close by construction: on the UR5 the upper arm can never be more than 38 mm from the base
capsule, and the forearm and wrist 2 capsules are always 3 mm apart. A single clearance cannot hold
for such pairs, so each pair must keep ``min(clearance_m, NEAR_PAIR_FRACTION · d_max)`` where
``d_max`` is the largest distance the pair can have anywhere in joint space (sampled
deterministically), and pairs whose distance does not depend on the joint angles at all are not
checked (like adjacent links). For all pairs that can move apart freely, this is ``clearance_m``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from urident.model.kinematics import AXIS_INDEX, frame_poses, packed_joints
from urident.model.pinocchio_model import TOOL_LINK, collision_link_pairs, floor_checked_links
from urident.model.robot import RobotSpec

try:  # compiled kernel (setup.py builds it when a C compiler is available)
    from urident.excitation import _capsule_kernel
except ImportError:  # pragma: no cover - exercised only where the build was skipped
    _capsule_kernel = None

KERNEL_MAX_CAPSULES = 64  # the kernel's stack buffer (the UR files have about 15)
NEAR_PAIR_FRACTION = 0.5
FIXED_PAIR_TOL_M = 1e-6
_EXTENT_SAMPLES = 4096
_EPS = 1e-12


@dataclass(frozen=True)
class CapsuleModel:
    """All capsules of one robot (C of them) and the checked pairs (P self + F floor)."""

    frame: np.ndarray          # (C,) joint frame index 0..5 of each capsule, −1 for the base
    a: np.ndarray              # (C, 3) segment start in its frame [m]
    b: np.ndarray              # (C, 3) segment end [m]
    radius: np.ndarray         # (C,)
    capsule_names: tuple[str, ...]   # 'base_0', 'elbow_0', … (as in the coal geometry model)
    first: np.ndarray          # (P,) capsule indices of the self-collision pairs
    second: np.ndarray         # (P,)
    floor: np.ndarray          # (F,) capsule indices checked against the floor plane
    floor_height_m: float
    pair_names: tuple[str, ...]  # (P + F,) 'shoulder_lift_0/base_0', …, 'wrist_1_0/floor'
    required: np.ndarray       # (P + F,) minimum distance each pair must keep [m]; −inf: not checked

    @property
    def n_pairs(self) -> int:
        return len(self.pair_names)

    def world_segments(self, spec: RobotSpec, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Segment end points in the base frame, each (N, C, 3), for joint angles (N, 6)."""
        return self._segments(*frame_poses(spec, q))

    def _segments(self, rot: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n = rot.shape[0]
        rot = np.concatenate([np.broadcast_to(np.eye(3), (n, 1, 3, 3)), rot[:, :6]], axis=1)
        pos = np.concatenate([np.zeros((n, 1, 3)), pos[:, :6]], axis=1)
        r = rot[:, self.frame + 1]                       # (N, C, 3, 3)
        o = pos[:, self.frame + 1]                       # (N, C, 3)
        pa = np.sum(r * self.a[None, :, None, :], axis=-1) + o
        pb = np.sum(r * self.b[None, :, None, :], axis=-1) + o
        return pa, pb

    def distances(self, spec: RobotSpec, q: np.ndarray) -> np.ndarray:
        """Signed distances (N, P + F) [m] (negative: penetration depth) for joint angles (N, 6)."""
        q = np.ascontiguousarray(np.atleast_2d(q), dtype=float)
        if _capsule_kernel is not None and len(self.frame) <= KERNEL_MAX_CAPSULES:
            out = np.empty((q.shape[0], self.n_pairs))  # the kernel writes every entry
            _capsule_kernel.distances(out, q, *packed_joints(spec), *self._kernel_arguments)
            return out
        return self.numpy_distances(spec, q)

    def numpy_distances(self, spec: RobotSpec, q: np.ndarray) -> np.ndarray:
        """:meth:`distances` in numpy (where the compiled kernel was not built)."""
        pa, pb = self.world_segments(spec, np.atleast_2d(q))
        self_d = (segment_distances(pa[:, self.first], pb[:, self.first],
                                    pa[:, self.second], pb[:, self.second])
                  - self.radius[self.first] - self.radius[self.second])
        low = np.minimum(pa[:, self.floor, 2], pb[:, self.floor, 2])
        floor_d = low - self.radius[self.floor] - self.floor_height_m
        return np.concatenate([self_d, floor_d], axis=1)

    @cached_property
    def _kernel_arguments(self) -> tuple[bytes, bytes, bytes, float]:
        capsules = np.column_stack([self.frame, self.a, self.b, self.radius]).astype(float)
        pairs = np.column_stack([self.first, self.second]).astype(np.int32)
        return (capsules.tobytes(), pairs.tobytes(), self.floor.astype(np.int32).tobytes(),
                float(self.floor_height_m))

    def distance_jacobians(self, spec: RobotSpec, q: np.ndarray,
                           where: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`distances` (N, P + F) and :meth:`distance_derivatives` (N, P + F, 6)."""
        return self.distances(spec, q), self.distance_derivatives(spec, q, where)

    def distance_derivatives(self, spec: RobotSpec, q: np.ndarray, where: np.ndarray | None = None) -> np.ndarray:
        """The distances' derivatives in the joint angles (N, P + F, 6) at the entries ``where``
        (N, P + F) is true, zero elsewhere (default: all); the compiled kernel where built, else
        :meth:`numpy_distance_derivatives` (the same formulas)."""
        q = np.ascontiguousarray(np.atleast_2d(q), dtype=float)
        if _capsule_kernel is not None and len(self.frame) <= KERNEL_MAX_CAPSULES:
            mask = np.ones((q.shape[0], self.n_pairs), dtype=bool) if where is None else where
            out = np.empty((q.shape[0], self.n_pairs, 6))  # the kernel writes every entry
            capsules, pairs, floor, _ = self._kernel_arguments
            _capsule_kernel.derivatives(out, q, *packed_joints(spec), capsules, pairs, floor,
                                        np.ascontiguousarray(mask, dtype=np.uint8))
            return out
        return self.numpy_distance_derivatives(spec, q, where)

    def numpy_distance_derivatives(self, spec: RobotSpec, q: np.ndarray,
                                   where: np.ndarray | None = None) -> np.ndarray:
        """:meth:`distance_derivatives` in numpy.

        A distance is that of the two closest points, which move with their links: its derivative
        is the unit normal between them times their velocities z_i × (c − o_i) for every joint i
        carrying them (the closest points' own motion along the segments does not change the
        distance to first order). Where two segments touch, the normal is undefined: zero there."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        n = q.shape[0]
        rows, pairs = np.nonzero(np.ones((n, self.n_pairs), dtype=bool) if where is None else where)
        jac = np.zeros((n, self.n_pairs, 6))
        rot, pos = frame_poses(spec, q)
        pa, pb = self._segments(rot, pos)
        axes = np.stack([rot[:, i, :, AXIS_INDEX[j.axis]] for i, j in enumerate(spec.joints)], axis=1)  # (N, 6, 3)
        origins = pos[:, :6]
        moves = self.frame[:, None] >= np.arange(6)[None, :]                     # (C, 6) joint i carries it

        def point_jacobian(c: np.ndarray, r: np.ndarray, capsules: np.ndarray) -> np.ndarray:  # (K, 6, 3)
            z, d = axes[r], c[:, None] - origins[r]
            v = np.stack([z[..., 1] * d[..., 2] - z[..., 2] * d[..., 1], z[..., 2] * d[..., 0] - z[..., 0] * d[..., 2],
                          z[..., 0] * d[..., 1] - z[..., 1] * d[..., 0]], axis=-1)   # z × d (np.cross is slower)
            return v * moves[capsules][:, :, None]

        own = pairs < len(self.first)
        r, p = rows[own], pairs[own]
        i, k = self.first[p], self.second[p]
        s, t = segment_closest(pa[r, i], pb[r, i], pa[r, k], pb[r, k])
        c1 = pa[r, i] + (pb[r, i] - pa[r, i]) * s[..., None]
        c2 = pa[r, k] + (pb[r, k] - pa[r, k]) * t[..., None]
        diff = c1 - c2
        gap = np.sqrt(np.einsum("...i,...i->...", diff, diff))
        normal = diff / np.where(gap > _EPS, gap, np.inf)[..., None]
        jac[r, p] = np.einsum("ki,kji->kj", normal, point_jacobian(c1, r, i) - point_jacobian(c2, r, k))
        r, p = rows[~own], pairs[~own]
        c = self.floor[p - len(self.first)]
        lower = pa[r, c, 2] <= pb[r, c, 2]
        low = np.where(lower[..., None], pa[r, c], pb[r, c])                       # (K, 3)
        jac[r, p] = point_jacobian(low, r, c)[..., 2]
        return jac

    def margins(self, spec: RobotSpec, q: np.ndarray) -> np.ndarray:
        """Distance minus required distance (N, P + F); ≥ 0 when safe (+inf for unchecked pairs)."""
        return self.distances(spec, q) - self.required


def kernel_available() -> bool:
    return _capsule_kernel is not None


def segment_distances(p1: np.ndarray, q1: np.ndarray, p2: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Distance between segments p1–q1 and p2–q2, all (..., 3), vectorised."""
    s, t = segment_closest(p1, q1, p2, q2)
    diff = (p1 + (q1 - p1) * s[..., None]) - (p2 + (q2 - p2) * t[..., None])
    return np.sqrt(np.einsum("...i,...i->...", diff, diff))


def segment_closest(p1: np.ndarray, q1: np.ndarray, p2: np.ndarray, q2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Parameters s, t ∈ [0, 1] of the closest points p1 + s(q1 − p1) and p2 + t(q2 − p2) of two
    segments, all (..., 3), vectorised (Ericson, Real-Time Collision Detection, 5.1.9, with the
    degenerate cases)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a = np.einsum("...i,...i->...", d1, d1)
    e = np.einsum("...i,...i->...", d2, d2)
    f = np.einsum("...i,...i->...", d2, r)
    c = np.einsum("...i,...i->...", d1, r)
    b = np.einsum("...i,...i->...", d1, d2)
    a_ok, e_ok = a > _EPS, e > _EPS
    safe_a, safe_e = np.where(a_ok, a, 1.0), np.where(e_ok, e, 1.0)
    denom = a * e - b * b
    s = np.where(denom > _EPS * np.maximum(a * e, _EPS),
                 np.clip((b * f - c * e) / np.where(denom > 0, denom, 1.0), 0.0, 1.0), 0.0)
    t = (b * s + f) / safe_e
    s = np.where(t < 0, np.clip(-c / safe_a, 0.0, 1.0), np.where(t > 1, np.clip((b - c) / safe_a, 0.0, 1.0), s))
    t = np.clip(t, 0.0, 1.0)
    # Degenerate segments (points).
    s = np.where(a_ok, s, 0.0)
    t = np.where(a_ok, t, np.clip(f / safe_e, 0.0, 1.0))
    s = np.where(a_ok & ~e_ok, np.clip(-c / safe_a, 0.0, 1.0), s)
    t = np.where(e_ok, t, 0.0)
    return s, t


def capsule_model(spec: RobotSpec, clearance_m: float, floor_height_m: float = 0.0) -> CapsuleModel:
    """The capsule model of ``spec`` with each pair's required distance for ``clearance_m``."""
    geometry = _geometry(spec, float(floor_height_m))
    d_max, fixed = _pair_extent(spec, float(floor_height_m))
    required = np.minimum(clearance_m, NEAR_PAIR_FRACTION * d_max)
    required[fixed] = -np.inf
    return CapsuleModel(**geometry, required=required)


def _geometry(spec: RobotSpec, floor_height_m: float) -> dict:
    frame, a, b, radius, names = [], [], [], [], []
    groups: dict[str, list[int]] = {}
    links = ([("base", -1, spec.base_collision)] + [(j.name, i, j.collision) for i, j in enumerate(spec.joints)]
             + [(TOOL_LINK, len(spec.joints) - 1, spec.tool_collision)])
    for link, index, capsules in links:
        groups[link] = []
        for k, cap in enumerate(capsules):
            groups[link].append(len(frame))
            frame.append(index)
            a.append(cap.a)
            b.append(cap.b)
            radius.append(cap.radius)
            names.append(f"{link}_{k}")
    first, second, pair_names = [], [], []
    for link1, link2 in collision_link_pairs(spec):
        for c1 in groups[link1]:
            for c2 in groups[link2]:
                first.append(c1)
                second.append(c2)
                pair_names.append(f"{names[c1]}/{names[c2]}")
    floor = [c for link in floor_checked_links(spec) for c in groups[link]]
    pair_names += [f"{names[c]}/floor" for c in floor]
    return dict(frame=np.array(frame, dtype=int), a=np.array(a, dtype=float).reshape(-1, 3),
                b=np.array(b, dtype=float).reshape(-1, 3), radius=np.array(radius, dtype=float),
                capsule_names=tuple(names), first=np.array(first, dtype=int),
                second=np.array(second, dtype=int), floor=np.array(floor, dtype=int),
                floor_height_m=floor_height_m, pair_names=tuple(pair_names))


_EXTENT_CACHE: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}


def _pair_extent(spec: RobotSpec, floor_height_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Largest sampled distance of each pair and whether its distance is configuration-independent
    (deterministic: a fixed-seed sample of joint space; cached per geometry)."""
    key = (floor_height_m, spec.tool_xyz.tobytes(), repr(spec.base_collision), repr(spec.tool_collision),
           repr([(j.xyz.tobytes(), j.rotation.tobytes(), j.axis, j.collision) for j in spec.joints]),
           tuple(collision_link_pairs(spec)), tuple(floor_checked_links(spec)))
    if key not in _EXTENT_CACHE:
        unchecked = CapsuleModel(**_geometry(spec, floor_height_m), required=np.zeros(0))
        q = np.random.default_rng(0).uniform(-np.pi, np.pi, (_EXTENT_SAMPLES, 6))
        d = unchecked.distances(spec, q)
        _EXTENT_CACHE[key] = (d.max(axis=0), (d.max(axis=0) - d.min(axis=0)) < FIXED_PAIR_TOL_M)
    d_max, fixed = _EXTENT_CACHE[key]
    return d_max.copy(), fixed.copy()


class CoalDistances:
    """The same pair distances from Pinocchio/coal (``pin.computeDistances``), one sample at a
    time; columns in :class:`CapsuleModel` order."""

    def __init__(self, spec: RobotSpec, capsules: CapsuleModel):
        import pinocchio as pin

        from urident.model.pinocchio_model import build_collision_model, build_model

        self._pin = pin
        self.model = build_model(spec)
        self.geom = build_collision_model(spec, self.model, capsules.floor_height_m)
        self.data = self.model.createData()
        self.gdata = pin.GeometryData(self.geom)
        index = {}
        for k, pair in enumerate(self.geom.collisionPairs):
            n1 = self.geom.geometryObjects[pair.first].name
            n2 = self.geom.geometryObjects[pair.second].name
            index[frozenset((n1, n2))] = k
        try:
            self.order = np.array([index[frozenset(name.split("/"))] for name in capsules.pair_names])
        except KeyError as exc:  # pragma: no cover - both sides come from the same pair lists
            raise RuntimeError(f"collision pair {exc} missing from the coal model") from None

    def distances(self, q: np.ndarray) -> np.ndarray:
        q = np.atleast_2d(np.asarray(q, dtype=float))
        out = np.empty((q.shape[0], len(self.order)))
        results = self.gdata.distanceResults
        for n, qn in enumerate(q):
            self._pin.computeDistances(self.model, self.data, self.geom, self.gdata, qn)
            all_d = np.array([r.min_distance for r in results])
            out[n] = all_d[self.order]
        return out
