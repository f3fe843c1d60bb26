"""URDF export of a physically consistent identified model.

Each link frame is the paper's joint frame K_i (joint origin = the robot file's fixed placement of
K_i in K_{i−1}), the inertial origin is the centre of mass ρ = h/m and the inertia is taken about it
(I_c = J − m(ρᵀρ·1 − ρρᵀ)). Viscous and Coulomb friction go to ``<dynamics damping friction>``; the
reflected rotor inertias i_G²·C_M have no URDF element and are written in a comment (Pinocchio users
add them as ``model.armature``). Collision geometry: each capsule of the robot file as a cylinder
and two spheres (URDF has no capsule). Only physically consistent parameters can be exported (a
URDF link needs a positive mass and a positive semi-definite inertia): :func:`check_exportable`.
The MJCF writer is :mod:`urident.sim.mjcf`.
"""

from __future__ import annotations

from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np

from urident.errors import ConfigError
from urident.model.parameters import COULOMB, N_PARAMS, ROTOR, VISCOUS, body_slice, inertia_tensor


def matrix_rpy(rotation: np.ndarray) -> np.ndarray:
    import pinocchio as pin

    return np.asarray(pin.rpy.matrixToRpy(np.asarray(rotation, dtype=float)))


def _fmt(values) -> str:
    return " ".join(f"{float(v):.12g}" for v in values)


def link_inertial(p10: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """(mass, centre of mass, inertia about the centre of mass) from ten parameters."""
    m = float(p10[0])
    if not m > 0:
        raise ConfigError(f"cannot export a link with mass {m:g} kg to URDF")
    com = np.asarray(p10[1:4], dtype=float) / m
    inertia = inertia_tensor(p10) - m * (com @ com * np.eye(3) - np.outer(com, com))
    return m, com, inertia


def check_exportable(standard, fmt: str = "URDF") -> np.ndarray:
    """``standard`` as a float 78-vector if a simulator can take it; else ConfigError with the one
    reason (which body's mass or pseudo-inertia, which drive parameter)."""
    from urident.ident.estimate_consistent import pseudo_inertia
    from urident.model.parameters import DRIVE, N_JOINTS, parameter_names

    p = np.asarray(standard, dtype=float)
    if p.shape != (N_PARAMS,):
        raise ConfigError(f"{fmt} export needs the {N_PARAMS} standard parameters, got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ConfigError(f"{fmt} export: the standard parameters are not all finite")
    for i in range(N_JOINTS):
        p10 = p[body_slice(i)]
        if not p10[0] > 0:
            raise ConfigError(f"{fmt} export needs physically consistent parameters: body {i + 1} has "
                              f"mass {p10[0]:g} kg")
        eig = float(np.linalg.eigvalsh(pseudo_inertia(p10)).min())
        if eig < -1e-7 * max(1.0, p10[0]):
            raise ConfigError(f"{fmt} export needs physically consistent parameters: body {i + 1}'s "
                              f"pseudo-inertia has eigenvalue {eig:.3g} < 0 (no real mass distribution)")
    names = parameter_names()
    for k in np.flatnonzero(p[DRIVE] < -1e-7) + DRIVE.start:
        raise ConfigError(f"{fmt} export needs physically consistent parameters: {names[k]} = {p[k]:.4g} < 0")
    return p


def _comment(text: str) -> str:
    return "<!-- " + text.replace("--", "- -") + " -->"


def _collision(capsules, indent: str) -> list[str]:
    """A capsule as a cylinder along a→b and a sphere at each end."""
    out = []
    for c in capsules:
        axis = np.asarray(c.b, float) - np.asarray(c.a, float)
        length = float(np.linalg.norm(axis))
        ends = [c.a, c.b] if length > 0 else [c.a]
        if length > 0:
            z = axis / length
            helper = np.array([1.0, 0, 0]) if abs(z[0]) < 0.9 else np.array([0, 1.0, 0])
            x = np.cross(helper, z)
            x /= np.linalg.norm(x)
            rot = np.column_stack([x, np.cross(z, x), z])
            mid = (np.asarray(c.a, float) + np.asarray(c.b, float)) / 2
            out += [f"{indent}<collision>", f'{indent}  <origin xyz="{_fmt(mid)}" rpy="{_fmt(matrix_rpy(rot))}"/>',
                    f'{indent}  <geometry><cylinder radius="{c.radius:.12g}" length="{length:.12g}"/></geometry>',
                    f"{indent}</collision>"]
        for end in ends:
            out += [f"{indent}<collision>", f'{indent}  <origin xyz="{_fmt(end)}" rpy="0 0 0"/>',
                    f'{indent}  <geometry><sphere radius="{c.radius:.12g}"/></geometry>', f"{indent}</collision>"]
    return out


def _inertial(indent: str, m: float, com, ic) -> list[str]:
    return [f"{indent}<inertial>", f'{indent}  <origin xyz="{_fmt(com)}" rpy="0 0 0"/>',
            f'{indent}  <mass value="{m:.12g}"/>',
            f'{indent}  <inertia ixx="{ic[0, 0]:.12g}" ixy="{ic[0, 1]:.12g}" ixz="{ic[0, 2]:.12g}" '
            f'iyy="{ic[1, 1]:.12g}" iyz="{ic[1, 2]:.12g}" izz="{ic[2, 2]:.12g}"/>', f"{indent}</inertial>"]


def payload_link(payload, parent: str = "tool0", indent: str = "  ") -> list[str]:
    """URDF lines of ``payload`` (a :class:`urident.model.payload.Payload`, flange frame) as a link
    ``payload`` on a fixed joint at ``parent`` (the flange frame ``tool0``)."""
    return ([f'{indent}<link name="payload">',
             *_inertial(indent + "  ", payload.mass_kg, payload.com_m, payload.inertia_kg_m2),
             f"{indent}</link>", f'{indent}<joint name="payload_fixed" type="fixed">',
             f'{indent}  <parent link="{parent}"/>', f'{indent}  <child link="payload"/>',
             f'{indent}  <origin xyz="0 0 0" rpy="0 0 0"/>', f"{indent}</joint>"])


def to_urdf(spec, standard: np.ndarray, name: str | None = None, notes=(), payload=None) -> str:
    """URDF text of ``spec``'s kinematics with the 78-vector ``standard``; ``notes``: more lines of
    the header comment (e.g. the identified terms URDF cannot express); ``payload``: a
    :class:`urident.model.payload.Payload`, a fixed link ``payload`` on the flange ``tool0``."""
    p = check_exportable(standard, "URDF")
    name = name or f"{spec.name}_identified"
    axes = {"x": "1 0 0", "y": "0 1 0", "z": "0 0 1"}
    out = ['<?xml version="1.0"?>', f'<robot name="{escape(name)}">',
           "  <!-- identified by urident; rotor inertias i_G^2*C_M [kg m^2] (not part of URDF): "
           + _fmt(p[ROTOR]) + " -->"]
    out += ["  " + _comment(line) for line in notes]
    out += ['  <link name="base_link">'] + _collision(spec.base_collision, "    ") + ["  </link>"]
    parent = "base_link"
    for i, joint in enumerate(spec.joints):
        m, com, ic = link_inertial(p[body_slice(i)])
        link = f"{joint.name}_link"
        out += [f'  <link name="{link}">', *_inertial("    ", m, com, ic),
                *_collision(joint.collision, "    "), "  </link>",
                f'  <joint name="{joint.name}" type="revolute">',
                f'    <parent link="{parent}"/>', f'    <child link="{link}"/>',
                f'    <origin xyz="{_fmt(joint.xyz)}" rpy="{_fmt(matrix_rpy(joint.rotation))}"/>',
                f'    <axis xyz="{axes[joint.axis]}"/>',
                f'    <limit lower="{joint.q_min:.12g}" upper="{joint.q_max:.12g}" '
                f'effort="{joint.tau_max:.12g}" velocity="{joint.qd_max:.12g}"/>',
                f'    <dynamics damping="{p[VISCOUS][i]:.12g}" friction="{p[COULOMB][i]:.12g}"/>',
                "  </joint>"]
        parent = link
    out += ['  <link name="tool0"/>', '  <joint name="tool0_fixed" type="fixed">',
            f'    <parent link="{parent}"/>', '    <child link="tool0"/>',
            f'    <origin xyz="{_fmt(spec.tool_xyz)}" rpy="{_fmt(matrix_rpy(spec.tool_rotation))}"/>',
            "  </joint>"]
    if payload is not None:
        out += payload_link(payload)
    out += ["</robot>", ""]
    return "\n".join(out)


def write_urdf(spec, standard: np.ndarray, path: str | Path, name: str | None = None,
               overwrite: bool = True, notes=(), payload=None) -> Path:
    """Write the URDF atomically, never through a symbolic link (``overwrite=False``: must be new)."""
    from urident.fileio import write_text_atomic

    path = Path(path)
    write_text_atomic(path, to_urdf(spec, standard, name, notes, payload), fsync=False, overwrite=overwrite)
    return path
