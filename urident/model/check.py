"""``urident model --robot FILE --check``: is a robot file self-consistent and plausible?

Loading already rejects malformed files (types, shapes, unknown keys, impossible inertias). This
goes further, for a file someone wrote by hand for an arm urident does not ship:

* the joint frames reproduce the DH table the file declares (each joint axis on the DH axis line,
  the tool frame on DH frame 6), naming the first key that disagrees;
* generation, controller rate and version agree;
* limits are within what a UR controller allows; the arm can hold itself against gravity;
* centres of mass lie on their link; the collision capsules do not overlap in the upright pose.

Each problem is one line ``FILE: key.path: message``, the format of every file error.
"""

from __future__ import annotations

import numpy as np

from urident.model.robot import RobotSpec

CONTROLLER_TO_BASE = np.diag([-1.0, -1.0, 1.0])  # K_0 is the controller base rotated by pi about z
FRAME_TOL_M = 1e-6
AXIS_TOL = 1e-9
MAX_POSITION_RAD = 2 * np.pi + 1e-3     # UR joints turn ±360°
MAX_VELOCITY_RAD_S = 2 * np.pi * 1.01   # fastest UR joint: 360°/s
MAX_ACCELERATION_RAD_S2 = 40.0          # far above any UR joint's practical limit
UPRIGHT_Q = np.array([0.0, -np.pi / 2, 0.0, -np.pi / 2, 0.0, 0.0])
RATES = {"cb3": (125.0, 3), "e-series": (500.0, 5)}
_AXES = {"x": 0, "y": 1, "z": 2}


def dh_poses(spec: RobotSpec, q: np.ndarray) -> list[np.ndarray]:
    """4×4 poses of UR's DH frames 1..6 in the controller base for joint angles ``q`` (6,),
    standard DH: Rz(θ)·Tz(d)·Tx(a)·Rx(α)."""
    out, m = [], np.eye(4)
    for d, a, alpha, qi in zip(spec.dh["d"], spec.dh["a"], spec.dh["alpha"], q):
        ct, st, ca, sa = np.cos(qi), np.sin(qi), np.cos(alpha), np.sin(alpha)
        m = m @ np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st],
                          [0, sa, ca, d], [0, 0, 0, 1]])
        out.append(m.copy())
    return out


def check_robot(spec: RobotSpec, samples: int = 16, seed: int = 0) -> list[str]:
    """Problems found in ``spec`` (empty if none), one line each naming the file and key."""
    problems = []
    where = str(spec.source)
    add = lambda key, message: problems.append(f"{where}: {key}: {message}")  # noqa: E731
    _check_controller(spec, add)
    _check_frames(spec, np.random.default_rng(seed).uniform(-np.pi, np.pi, (samples, 6)), add)
    _check_limits(spec, add)
    _check_masses(spec, add)
    _check_collision(spec, add)
    return problems


def _check_controller(spec: RobotSpec, add) -> None:
    rate, major = RATES[spec.generation]
    if abs(spec.controller_rate_hz - rate) > 1e-9:
        add("controller_rate_hz", f"{spec.generation} controllers run at {rate:g} Hz, not "
                                  f"{spec.controller_rate_hz:g}")
    if spec.controller_version[0] != major:
        add("controller_version", f"{spec.generation} controllers run software {major}.x, not "
                                  f"{'.'.join(map(str, spec.controller_version))}")
    if not spec.model:
        add("model", "missing: give the arm model as UR names it (e.g. UR5e), which urident run "
                     "compares with the controller's")


def _check_frames(spec: RobotSpec, qs: np.ndarray, add) -> None:
    from urident.model.kinematics import frame_poses

    rot, pos = frame_poses(spec, qs)
    rot, pos = CONTROLLER_TO_BASE @ rot, pos @ CONTROLLER_TO_BASE.T
    for k, q in enumerate(qs):
        dh = [np.eye(4)] + dh_poses(spec, q)
        for i, joint in enumerate(spec.joints):
            # Joint i turns about z of DH frame i-1, through its origin.
            axis_dh, origin_dh = dh[i][:3, 2], dh[i][:3, 3]
            axis = rot[k, i][:, _AXES[joint.axis]]
            if axis @ axis_dh < 1 - AXIS_TOL:
                add(f"joints[{i}].rpy", f"joint axis {joint.axis} of K_{i + 1} does not point along "
                                        f"the declared DH axis (joint {i + 1}) at q = {_show(q)}; "
                                        f"check its rpy and axis"
                                        + (f", and joints[{i - 1}].rpy (a turn about "
                                           f"joint {i}'s own axis shows only here)" if i else ""))
                return
            offset = pos[k, i] - origin_dh
            off_line = np.linalg.norm(offset - (offset @ axis_dh) * axis_dh)
            if off_line > FRAME_TOL_M:
                add(f"joints[{i}].xyz", f"K_{i + 1} is {off_line * 1000:.3f} mm off the declared DH "
                                        f"axis of joint {i + 1} at q = {_show(q)}")
                return
        error = np.linalg.norm(pos[k, 6] - dh[6][:3, 3])
        if error > FRAME_TOL_M:
            add("tool.xyz", f"the tool frame is {error * 1000:.3f} mm from DH frame 6 at q = {_show(q)} "
                            f"(the joint frames match the DH axes; check tool.xyz and dh.d[5])")
            return
        if np.abs(rot[k, 6] - dh[6][:3, :3]).max() > 1e-6:
            add("tool.rpy", f"the tool frame is not oriented as DH frame 6 at q = {_show(q)}")
            return


def _check_limits(spec: RobotSpec, add) -> None:
    for i, j in enumerate(spec.joints):
        if j.q_min < -MAX_POSITION_RAD or j.q_max > MAX_POSITION_RAD:
            add(f"joints[{i}].position_limits", f"[{j.q_min:g}, {j.q_max:g}] rad is beyond ±2π "
                                                f"(UR joints turn ±360°; limits are in rad)")
        if j.qd_max > MAX_VELOCITY_RAD_S:
            add(f"joints[{i}].velocity_limit", f"{j.qd_max:g} rad/s is above any UR joint's "
                                               f"(at most 2π rad/s = 360°/s; limits are in rad/s)")
        if j.qdd_max > MAX_ACCELERATION_RAD_S2:
            add(f"joints[{i}].acceleration_limit", f"{j.qdd_max:g} rad/s² is implausibly high "
                                                   f"(at most {MAX_ACCELERATION_RAD_S2:g})")


def _check_masses(spec: RobotSpec, add) -> None:
    from urident.model.regressor import joint_torques

    for i, j in enumerate(spec.joints):
        extent = max([np.linalg.norm(c.a) + c.radius for c in j.collision]
                     + [np.linalg.norm(c.b) + c.radius for c in j.collision]
                     + [np.linalg.norm(spec.joints[i + 1].xyz) if i + 1 < len(spec.joints)
                        else np.linalg.norm(spec.tool_xyz)])
        if np.linalg.norm(j.com) > extent + 0.05:
            add(f"joints[{i}].link.com", f"{np.linalg.norm(j.com):.3f} m from K_{i + 1}, beyond the "
                                         f"link ({extent:.3f} m): is it in the DH frame, or in mm?")
    # The arm must hold itself: static torques over many poses within the torque limits.
    q = np.random.default_rng(1).uniform(-np.pi, np.pi, (256, 6))
    zero = np.zeros_like(q)
    gravity = np.abs(joint_torques(spec, spec.nominal_params, q, zero, zero)).max(axis=0)
    for i in np.flatnonzero(gravity > spec.tau_max):
        add(f"joints[{i}].torque_limit", f"{spec.tau_max[i]:g} N m is below the arm's own gravity "
                                         f"torque ({gravity[i]:.1f} N m): check the link masses and "
                                         f"centres of mass (kg, m)")


def _check_collision(spec: RobotSpec, add) -> None:
    import pinocchio as pin

    from urident.model.pinocchio_model import build_collision_model, build_model

    model = build_model(spec)
    geom = build_collision_model(spec, model)
    data, gdata = model.createData(), pin.GeometryData(geom)
    pin.computeDistances(model, data, geom, gdata, UPRIGHT_Q)
    for pair, result in zip(geom.collisionPairs, gdata.distanceResults):
        if result.min_distance < 0:
            names = [geom.geometryObjects[k].name for k in (pair.first, pair.second)]
            add("allowed_contacts", f"capsules {names[0]} and {names[1]} overlap by "
                                    f"{-result.min_distance * 1000:.1f} mm in the upright pose "
                                    f"q = {_show(UPRIGHT_Q)}: shrink them, or list the link pair "
                                    f"under allowed_contacts")
    for i, j in enumerate(spec.joints):
        if not j.collision:
            add(f"joints[{i}].link.collision", "no capsule: this link is not checked for collisions")


def _show(q: np.ndarray) -> str:
    return "[" + ", ".join(f"{v:.2f}" for v in q) + "]"
