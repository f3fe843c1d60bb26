"""MuJoCo, the optional simulator: the only module that imports ``mujoco``.

``inverse_dynamics(xml, q, qd, qdd)`` runs ``mj_inverse`` at every state and returns the joint
torques (N, 6) [N·m] the model needs: rigid body + armature·q̈ + damping·q̇ + the frictionloss
constraint's force (+ gravity, from the file's ``<option gravity>``). Contacts are disabled for it:
a recorded trajectory passed the collision checks, and a touching capsule pair must not add forces.
"""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Iterator

import numpy as np

from urident.errors import ConfigError, UridentError

INSTALL_HINT = "MuJoCo is not installed: pip install 'urident[mujoco]' (or '.[mujoco]' in a checkout)"


class MujocoModelError(ConfigError):
    """An MJCF file MuJoCo cannot load, or one that does not fit the robot."""


def import_mujoco():
    try:
        import mujoco
    except ImportError:
        raise UridentError(INSTALL_HINT) from None
    return mujoco


@contextlib.contextmanager
def _warnings_kept(mujoco) -> Iterator[list[str]]:
    """MuJoCo's warnings collected instead of printed and appended to MUJOCO_LOG.TXT in the working
    directory (what it does without a user handler)."""
    said: list[str] = []
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(lambda msg: said.append(" ".join(str(msg).split())))
    try:
        yield said
    finally:
        mujoco.set_mju_user_warning(previous)


def load_model(source: str | Path, *, text: bool = False):
    """``mujoco.MjModel`` from an MJCF file (or its ``text``); MujocoModelError naming the file, also
    when MuJoCo warns while loading it (a NaN in the XML, for one)."""
    mujoco = import_mujoco()
    label = "MJCF text" if text else str(source)
    with _warnings_kept(mujoco) as said:
        try:
            model = (mujoco.MjModel.from_xml_string(str(source)) if text
                     else mujoco.MjModel.from_xml_path(str(source)))
        except ValueError as exc:   # MuJoCo's parse/compile errors
            message = " ".join(str(exc).split())
            raise MujocoModelError(f"{label}: MuJoCo cannot load it: {message}"
                                   + (f" (MuJoCo warned: {said[0]})" if said else "")) from None
    if said:
        raise MujocoModelError(f"{label}: MuJoCo warns: {said[0]}")
    return model


def hinge_joints(model) -> list[str]:
    """Names of the model's hinge joints in tree order."""
    mujoco = import_mujoco()
    return [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or f"joint{j}"
            for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]


def inverse_dynamics(model, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, *,
                     frictionloss: bool = True) -> np.ndarray:
    """(N, 6) joint torques of ``model`` (an MjModel, an MJCF path) at the states (N, 6)."""
    mujoco = import_mujoco()
    if not hasattr(model, "nv"):
        model = load_model(model)
    if model.nv != q.shape[1] or model.nq != q.shape[1]:
        raise MujocoModelError(f"the MuJoCo model has {model.nv} degrees of freedom, the log {q.shape[1]}")
    flags = model.opt.disableflags
    model.opt.disableflags = flags | int(mujoco.mjtDisableBit.mjDSBL_CONTACT) | (
        0 if frictionloss else int(mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS))
    try:
        with _warnings_kept(mujoco) as said:
            data = mujoco.MjData(model)
            out = np.empty_like(np.asarray(q, dtype=float))
            for k in range(q.shape[0]):
                data.qpos[:] = q[k]
                data.qvel[:] = qd[k]
                data.qacc[:] = qdd[k]
                mujoco.mj_inverse(model, data)
                out[k] = data.qfrc_inverse
        if said or not np.all(np.isfinite(out)):
            raise MujocoModelError("MuJoCo's inverse dynamics of the model "
                                   + (f"warns: {said[0]}" if said else "is not finite at every state"))
        return out
    finally:
        model.opt.disableflags = flags
