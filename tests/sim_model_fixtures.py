"""Simulator models of a UR arm as users have them, written here (no third-party file is copied):

* :func:`menagerie_like_mjcf`: the layout MuJoCo Menagerie's UR models use (a ``base`` body turned
  about the vertical, one body per link whose frame is the joint frame turned about its axis, joint
  anchors moved along their axes, link lengths rounded, default classes with armature and damping
  in an included file, a childclass, degrees, visual meshes whose files are absent, position
  actuators, a keyframe, a flange and a gripper body with finger joints);
* :func:`dh_mjcf`: a chain built straight from the DH table (body i = DH frame i − 1, every joint
  about its body's z at the body origin, joint 1 at the base origin);
* :func:`ros_like_urdf`: the layout of UR's ROS description (``base_link`` → ``base_link_inertia``
  turned by π, DH frames, ``flange`` and ``tool0``, zero ``<dynamics>``).

Masses come from a 78-vector ``p`` in the robot's joint frames K_i (placed in the model's bodies
exactly, whatever the frames), so the torques of the model are known.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

AXES = {"x": np.array([1.0, 0, 0]), "y": np.array([0, 1.0, 0]), "z": np.array([0, 0, 1.0])}


def _fmt(values, digits=12) -> str:
    return " ".join(f"{float(v):.{digits}g}" for v in np.atleast_1d(values))


def _quat(r: np.ndarray) -> np.ndarray:
    x, y, z, w = Rotation.from_matrix(r).as_quat()
    return np.array([w, x, y, z])


def _rz(yaw: float) -> np.ndarray:
    return Rotation.from_euler("z", yaw).as_matrix()


#: UR's DH base frame is the robot file's base frame turned by π about the vertical
DH_BASE_YAW = np.pi


def link_inertials_world(spec, p: np.ndarray, yaw: float = 0.0):
    """Per link (mass, CoM, inertia about the CoM) at q = 0 of the 78-vector ``p``, in the robot's
    base frame turned by ``yaw`` about z."""
    from urident.ident.urdf import link_inertial
    from urident.model.kinematics import frame_poses
    from urident.model.parameters import body_slice

    rot, pos = frame_poses(spec, np.zeros((1, 6)))
    out = []
    for i in range(6):
        m, com, ic = link_inertial(p[body_slice(i)])
        w = _rz(yaw)
        out.append((m, w @ (pos[0, i] + rot[0, i] @ com), w @ rot[0, i] @ ic @ rot[0, i].T @ w.T))
    return out


def _inertial(m, com_w, ic_w, r_body, p_body, digits=12) -> str:
    com = r_body.T @ (com_w - p_body)
    ic = r_body.T @ ic_w @ r_body
    return (f'<inertial pos="{_fmt(com, digits)}" mass="{m:.{digits}g}" fullinertia="'
            f'{_fmt([ic[0, 0], ic[1, 1], ic[2, 2], ic[0, 1], ic[0, 2], ic[1, 2]], digits)}"/>')


def menagerie_like_mjcf(spec, p: np.ndarray, folder: Path, *, yaw: float = np.pi / 2, round_m: float = 0.001,
                        shift_m=(0.0, 0.03, -0.02, 0.05, 0.01, -0.04), twist=(0.3, -0.5, 1.0, 0.0, 0.7, -1.2),
                        prefix: str = "", gripper: bool = True, finger: str = "slide", armature: float = 0.1,
                        damping=(200.0, 200.0, 200.0, 15.0, 15.0, 15.0), name: str = "arm.xml") -> Path:
    """The model in ``folder`` (with ``classes.xml``, included); returns the main file."""
    from urident.model.kinematics import frame_poses

    rot, pos = frame_poses(spec, np.zeros((1, 6)))
    inertials = link_inertials_world(spec, p)
    # body i: K_i turned about joint i's axis by twist_i, in the base body (the robot's base frame;
    # the base body is turned by yaw in the world)
    frames = []
    for i, joint in enumerate(spec.joints):
        r = rot[0, i] @ Rotation.from_rotvec(twist[i] * AXES[joint.axis]).as_matrix()
        frames.append((r, pos[0, i]))
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "classes.xml").write_text(f"""<mujoco>
  <default>
    <joint axis="0 1 0" range="-360 360"/>
    <position ctrlrange="-6.2831 6.2831"/>
    <default class="visual"><geom type="mesh" contype="0" conaffinity="0" group="2"/></default>
    <default class="collision"><geom type="capsule" group="3"/></default>
    <default class="big"><joint armature="{armature}" damping="{damping[0]}"/>
      <position kp="3500" forcerange="-150 150"/></default>
    <default class="big_limited"><joint armature="{armature}" damping="{damping[2]}" range="-180 180"/>
      <position kp="3500" forcerange="-150 150"/></default>
    <default class="small"><joint armature="{armature}" damping="{damping[3]}"/>
      <position kp="3000" forcerange="-28 28"/></default>
  </default>
</mujoco>
""")
    classes = ["big", "big", "big_limited", "small", "small", "small"]
    lines = ['<mujoco model="arm">', '  <!-- a user\'s model: kept comment -->',
             '  <compiler angle="degree" meshdir="assets" autolimits="true"/>', '  <include file="classes.xml"/>',
             '  <asset>'] + [f'    <mesh file="link{i}.obj"/>' for i in range(7)] + ['  </asset>', '  <worldbody>',
             f'    <body name="base" euler="0 0 {np.rad2deg(yaw):.12g}">',
             '      <inertial mass="4.0" pos="0 0 0" diaginertia="0.0044 0.0044 0.0072"/>',
             '      <geom mesh="link0" class="visual"/>']
    indent = "      "
    parent_r, parent_p = np.eye(3), np.zeros(3)      # the base body's frame
    for i, joint in enumerate(spec.joints):
        r, p_w = frames[i]
        rel_r = parent_r.T @ r
        rel_p = parent_r.T @ (p_w - parent_p)
        if round_m:
            rel_p = np.round(rel_p / round_m) * round_m
        p_w = parent_p + parent_r @ rel_p                  # the rounded chain
        m, com_w, ic_w = inertials[i]
        # MuJoCo's euler="a b c" in degrees with its default eulerseq xyz (axes moving with the frame)
        euler = Rotation.from_matrix(rel_r).as_euler("XYZ", degrees=True)
        orient = f'euler="{_fmt(euler)}"' if i % 2 else f'quat="{_fmt(_quat(rel_r))}"'
        child = ' childclass="small"' if i == 3 else ""
        lines += [f'{indent}<body name="{prefix}link{i + 1}" pos="{_fmt(rel_p)}" {orient}{child}>',
                  f"{indent}  " + _inertial(m, com_w, ic_w, r, p_w),
                  f'{indent}  <joint name="{prefix}{joint.name}_joint" ' + ("" if i >= 3 else f'class="{classes[i]}" ')
                  + f'pos="{_fmt(shift_m[i] * AXES[joint.axis])}" axis="{_fmt(AXES[joint.axis])}"/>',
                  f'{indent}  <geom mesh="link{i + 1}" class="visual"/>',
                  f'{indent}  <geom class="collision" size="0.04 0.05" pos="{_fmt(r.T @ (com_w - p_w))}"/>']
        indent += "  "
        parent_r, parent_p = r, p_w
    if gripper:
        # flange and a two-finger gripper welded on: mass the arm's last joint carries, fingers held
        tool = pos[0, 5] + rot[0, 5] @ spec.tool_xyz
        rel = parent_r.T @ (tool - parent_p)
        lines += [f'{indent}<body name="{prefix}flange" pos="{_fmt(rel)}">',
                  f'{indent}  <body name="{prefix}gripper" pos="0 0 0">',
                  f'{indent}    <inertial mass="0.5" pos="0 0.03 0" diaginertia="0.001 0.001 0.001"/>',
                  f'{indent}    <body name="{prefix}finger_left" pos="0 0.06 0.02">',
                  f'{indent}      <inertial mass="0.05" pos="0 0.01 0" diaginertia="1e-5 1e-5 1e-5"/>',
                  f'{indent}      <joint name="{prefix}finger_left_joint" type="{finger}" axis="0 0 1" range="0 0.04"/>',
                  f"{indent}    </body>",
                  f'{indent}    <body name="{prefix}finger_right" pos="0 0.06 -0.02">',
                  f'{indent}      <inertial mass="0.05" pos="0 0.01 0" diaginertia="1e-5 1e-5 1e-5"/>',
                  f'{indent}      <joint name="{prefix}finger_right_joint" type="{finger}" axis="0 0 -1" range="0 0.04"/>',
                  f"{indent}    </body>", f"{indent}  </body>", f"{indent}</body>"]
    for _ in range(6):
        indent = indent[:-2]
        lines.append(f"{indent}</body>")
    lines += ["    </body>", "  </worldbody>", "  <actuator>"]
    for i, joint in enumerate(spec.joints):
        lines.append(f'    <position class="{classes[i]}" name="{prefix}{joint.name}" joint="{prefix}{joint.name}_joint"/>')
    lines += ["  </actuator>", "  <keyframe>",
              f'    <key name="home" qpos="-1.5708 -1.5708 1.5708 -1.5708 -1.5708 0{" 0 0" if gripper else ""}" '
              'ctrl="-1.5708 -1.5708 1.5708 -1.5708 -1.5708 0"/>',
              "  </keyframe>", "</mujoco>", ""]
    path = folder / name
    path.write_text("\n".join(lines))
    return path


def dh_frames(spec) -> list[tuple[np.ndarray, np.ndarray]]:
    """World poses (R, p) at q = 0 of DH frames 0 … 6 of ``spec.dh``."""
    d, a, alpha = (np.asarray(spec.dh[k], float) for k in ("d", "a", "alpha"))
    out = [(np.eye(3), np.zeros(3))]
    for i in range(6):
        r, p = out[-1]
        rx = Rotation.from_euler("x", alpha[i]).as_matrix()
        out.append((r @ rx, p + r @ np.array([a[i], 0.0, d[i]])))
    return out


def dh_mjcf(spec, p: np.ndarray, path: Path, *, armature=0.0, damping=0.0) -> Path:
    """Body i = DH frame i − 1 (joint i about its z at its origin), joints ``joint1`` …"""
    frames = dh_frames(spec)
    inertials = link_inertials_world(spec, p, DH_BASE_YAW)
    lines = ['<mujoco model="dh">', '  <compiler angle="radian"/>', "  <worldbody>"]
    indent = "    "
    parent_r, parent_p = np.eye(3), np.zeros(3)
    for i in range(6):
        r, p_w = frames[i]
        m, com_w, ic_w = inertials[i]
        lines += [f'{indent}<body name="link{i + 1}" pos="{_fmt(parent_r.T @ (p_w - parent_p))}" '
                  f'quat="{_fmt(_quat(parent_r.T @ r))}">',
                  f"{indent}  " + _inertial(m, com_w, ic_w, r, p_w),
                  f'{indent}  <joint name="joint{i + 1}" axis="0 0 1" armature="{armature}" damping="{damping}"/>']
        indent += "  "
        parent_r, parent_p = r, p_w
    for _ in range(6):
        indent = indent[:-2]
        lines.append(f"{indent}</body>")
    lines += ["  </worldbody>", "</mujoco>", ""]
    path.write_text("\n".join(lines))
    return path


def _rpy(r: np.ndarray) -> np.ndarray:
    return Rotation.from_matrix(r).as_euler("xyz")     # URDF's fixed-axis roll, pitch, yaw


def ros_like_urdf(spec, p: np.ndarray, path: Path, prefix: str = "", fingers: bool = False) -> Path:
    """UR's ROS description layout: base_link → base_link_inertia (turned by π) → DH-frame links,
    wrist_3_link → flange → tool0; zero <dynamics>."""
    frames = dh_frames(spec)
    inertials = link_inertials_world(spec, p, DH_BASE_YAW)
    turn = _rz(np.pi)                                   # base_link_inertia in base_link
    names = ["shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link", "wrist_2_link", "wrist_3_link"]
    joints = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
              "wrist_3_joint"]
    out = [f'<?xml version="1.0"?>', f'<robot name="{prefix}ur">', f'  <link name="{prefix}base_link"/>',
           f'  <link name="{prefix}base_link_inertia"><inertial><origin xyz="0 0 0" rpy="0 0 0"/>'
           f'<mass value="4.0"/><inertia ixx="0.0044" ixy="0" ixz="0" iyy="0.0044" iyz="0" izz="0.0072"/></inertial></link>',
           f'  <joint name="{prefix}base_link-base_link_inertia" type="fixed"><parent link="{prefix}base_link"/>'
           f'<child link="{prefix}base_link_inertia"/><origin xyz="0 0 0" rpy="0 0 {np.pi:.12g}"/></joint>']
    parent, parent_r, parent_p = f"{prefix}base_link_inertia", np.eye(3), np.zeros(3)
    for i in range(6):
        # link i's frame: DH frame i - 1 (joint i turns it about its z, through its origin)
        r, p_w = frames[i]
        m, com_w, ic_w = inertials[i]
        com, ic = r.T @ (com_w - p_w), r.T @ ic_w @ r
        out += [f'  <link name="{prefix}{names[i]}"><inertial><origin xyz="{_fmt(com)}" rpy="0 0 0"/>'
                f'<mass value="{m:.12g}"/><inertia ixx="{ic[0, 0]:.12g}" ixy="{ic[0, 1]:.12g}" ixz="{ic[0, 2]:.12g}" '
                f'iyy="{ic[1, 1]:.12g}" iyz="{ic[1, 2]:.12g}" izz="{ic[2, 2]:.12g}"/></inertial></link>',
                f'  <joint name="{prefix}{joints[i]}" type="revolute"><parent link="{parent}"/>'
                f'<child link="{prefix}{names[i]}"/><origin xyz="{_fmt(parent_r.T @ (p_w - parent_p))}" '
                f'rpy="{_fmt(_rpy(parent_r.T @ r))}"/><axis xyz="0 0 1"/>'
                f'<limit lower="-6.28" upper="6.28" effort="150" velocity="3.14"/>'
                f'<dynamics damping="0" friction="0"/></joint>']
        parent, parent_r, parent_p = f"{prefix}{names[i]}", r, p_w
    out += [f'  <link name="{prefix}flange"/>', f'  <link name="{prefix}tool0"/>',
            f'  <joint name="{prefix}wrist_3-flange" type="fixed"><parent link="{parent}"/><child link="{prefix}flange"/>'
            f'<origin xyz="0 0 {spec.dh["d"][5]:.12g}" rpy="0 {-np.pi / 2:.12g} {-np.pi / 2:.12g}"/></joint>',
            f'  <joint name="{prefix}flange-tool0" type="fixed"><parent link="{prefix}flange"/><child link="{prefix}tool0"/>'
            f'<origin xyz="0 0 0" rpy="{np.pi / 2:.12g} 0 {np.pi / 2:.12g}"/></joint>']
    if fingers:      # a two-finger gripper on tool0: a revolute finger and a mimic one
        for k, side in enumerate(("left", "right")):
            mimic = f'<mimic joint="{prefix}finger_left_joint"/>' if k else ""
            out += [f'  <link name="{prefix}finger_{side}"><inertial><origin xyz="0 0 0.02" rpy="0 0 0"/>'
                    f'<mass value="0.05"/><inertia ixx="1e-5" ixy="0" ixz="0" iyy="1e-5" iyz="0" izz="1e-5"/>'
                    f'</inertial></link>',
                    f'  <joint name="{prefix}finger_{side}_joint" type="revolute"><parent link="{prefix}tool0"/>'
                    f'<child link="{prefix}finger_{side}"/><origin xyz="0 {0.02 - 0.04 * k} 0.05" rpy="0 0 0"/>'
                    f'<axis xyz="1 0 0"/><limit lower="0" upper="0.8" effort="10" velocity="1"/>{mimic}</joint>']
    out += ["</robot>", ""]
    path.write_text("\n".join(out))
    return path
