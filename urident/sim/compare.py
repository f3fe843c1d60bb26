"""What a user's simulator model says about the arm, set beside the robot file: the geometry left
after placing its base (:mod:`urident.sim.chain`) and the torque that geometry costs on a run, its
link masses and first moments, and its joint drive terms (armature, damping, frictionloss)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


def geometry_torque(sim, spec, q, qd, qdd) -> np.ndarray:
    """(N, 6) the model's rigid-body torque minus the same masses and armature on the robot file's
    geometry (:meth:`SimModel.link_params` through the robot's regressor): what the model's axis
    offsets cost [N·m]."""
    from urident.model import regressor_blocks
    from urident.model.parameters import standard_vector

    zeros = np.zeros(6)
    p = standard_vector(list(sim.link_params(spec)), sim.drive()["armature"], zeros, zeros)
    return sim.rigid(q, qd, qdd) - regressor_blocks(spec, q, qd, qdd) @ p


@dataclass(frozen=True)
class ModelComparison:
    """:func:`model_against_robot`'s document (``to_dict()``) and its report lines."""

    document: dict = field(repr=False)

    @property
    def link_mass_kg(self) -> list[float]:
        return list(self.document["link_mass_kg"])

    def to_dict(self) -> dict:
        return self.document

    def lines(self, spec, fmt: str) -> list[str]:
        return format_model_against_robot(self.document, spec, fmt)


def compare_model(sim, spec, q=None, qd=None, qdd=None) -> ModelComparison:
    """:func:`model_against_robot` as a :class:`ModelComparison`."""
    return ModelComparison(model_against_robot(sim, spec, q, qd, qdd))


def model_against_robot(sim, spec, q=None, qd=None, qdd=None) -> dict:
    """The model's geometry and dynamics beside the robot file's (JSON-ready); with states (N, 6)
    also the RMS torque of the geometry per joint on them."""
    from urident.model.parameters import body_slice

    links = sim.link_params(spec)
    nominal = np.array([spec.nominal_params[body_slice(i)] for i in range(6)])
    drive = sim.drive()
    out = {"alignment": sim.alignment.as_dict(),
           "link_mass_kg": links[:, 0].tolist(), "robot_file_mass_kg": nominal[:, 0].tolist(),
           "first_moment_kg_m": links[:, 1:4].tolist(), "robot_file_first_moment_kg_m": nominal[:, 1:4].tolist(),
           "first_moment_difference_kg_m": np.linalg.norm(links[:, 1:4] - nominal[:, 1:4], axis=1).tolist(),
           "armature_kg_m2": drive["armature"].tolist(), "damping_nm_s_per_rad": drive["damping"].tolist(),
           "frictionloss_nm": drive["frictionloss"].tolist(), "missing_meshes": list(sim.missing_meshes),
           **({"notes": list(sim.notes)} if sim.notes else {})}
    if q is not None:
        tau = geometry_torque(sim, spec, q, qd, qdd)
        out["geometry_torque_rms_nm"] = np.sqrt(np.mean(tau ** 2, axis=0)).tolist()
    return out


def format_model_against_robot(doc: dict, spec, fmt: str) -> list[str]:
    """Report lines of :func:`model_against_robot`."""
    a = doc["alignment"]
    row = lambda values, f="7.3f": " ".join(f"{v:{f}}" for v in values)  # noqa: E731
    out = [f"The model against {spec.name}'s robot file (joints 1-6):",
           f"  base placed on the robot's: turned {a['yaw_deg']:.2f}° about the vertical, moved "
           f"({', '.join(f'{1000 * v:.1f}' for v in a['translation_m'])}) mm",
           "  axis line offset [mm]            " + row(a["axis_offset_mm"], "7.2f"),
           "  axis angle [°]                   " + row(a["axis_angle_deg"], "7.3f")]
    if "geometry_torque_rms_nm" in doc:
        out.append("  torque of the geometry [N·m RMS] " + row(doc["geometry_torque_rms_nm"]))
    out += ["  link mass [kg]                   " + row(doc["link_mass_kg"]),
            "  robot file's mass [kg]           " + row(doc["robot_file_mass_kg"]),
            "  first moment m·ρ off by [kg·m]   " + row(doc["first_moment_difference_kg_m"], "7.4f"),
            "  armature [kg·m²]                 " + row(doc["armature_kg_m2"], "7.4f")
            + ("" if fmt == "mjcf" else "   (URDF has none)"),
            "  damping [N·m·s/rad]              " + row(doc["damping_nm_s_per_rad"], "7.2f"),
            "  frictionloss [N·m]               " + row(doc["frictionloss_nm"], "7.2f")]
    out.append("  " + ("MJCF holds each of these: <inertial> mass, pos, inertia; joint armature, damping, "
                       "frictionloss (Coulomb friction as a clipped line, urident writes it tanh-like)"
                       if fmt == "mjcf" else "URDF holds <inertial> and <dynamics damping friction>; no armature"))
    out += [f"  note: {line}" for line in doc.get("notes", ())]
    if doc["missing_meshes"]:
        missing = doc["missing_meshes"]
        out.append(f"  mesh files not found (checked without them): {', '.join(missing[:3])}"
                   + (f" … ({len(missing)} files)" if len(missing) > 3 else ""))
    return out
