"""Robot descriptions: one YAML file per robot under ``urident/model/robots/``, loaded into a
frozen :class:`RobotSpec`.

A robot file holds the joint frames in the paper's convention (fixed placement of K_i in K_{i-1},
then a rotation about the joint axis), the joint limits, the drive (gear ratio, motor torque
constant, reflected rotor inertia, friction), the nominal link inertial parameters and capsule
collision geometry. See ``robots/ur5.yaml`` for the documented format.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable

import numpy as np

from urident.errors import ConfigError, UnknownRobotError, shown
from urident.model.parameters import N_JOINTS, N_PARAMS, inertia_matrix, standard_from_links  # noqa: F401  (N_PARAMS: re-exported)
from urident.yamlio import Fields, load_yaml

ROBOTS_DIR = Path(__file__).parent / "robots"

_TOP_KEYS = {"name", "description", "model", "generation", "controller_rate_hz", "controller_version",
             "reach_m", "payload_kg", "nominal", "gravity", "dh", "base_collision", "tool", "joints",
             "allowed_contacts"}
# Per-joint values a robot file may mark as approximations (`nominal: [...]`), with report wording.
NOMINAL_KEYS = {"inertia_com": "link inertias", "rotor_inertia": "rotor inertias",
                "viscous_friction": "viscous friction", "coulomb_friction": "Coulomb friction",
                "torque_constant": "torque constants", "gear_ratio": "gear ratios",
                "acceleration_limit": "acceleration limits", "torque_limit": "torque limits"}
_JOINT_KEYS = {"name", "xyz", "rpy", "axis", "position_limits", "velocity_limit",
               "acceleration_limit", "torque_limit", "gear_ratio", "torque_constant",
               "rotor_inertia", "viscous_friction", "coulomb_friction", "link"}
_LINK_KEYS = {"mass", "com", "inertia_com", "collision"}
_CAPSULE_KEYS = {"a", "b", "radius"}


@dataclass(frozen=True)
class Capsule:
    """A segment a→b [m] swept by a sphere of ``radius`` [m], in its body's frame."""

    a: np.ndarray
    b: np.ndarray
    radius: float


@dataclass(frozen=True)
class ToolCapsule:
    """A tool's bounding capsule on the flange: its axis runs from the flange centre ``length_m``
    out along the flange z axis, swept by a sphere of ``radius_m`` (so it encloses a cylinder of
    that radius and length standing on the flange) [m]."""

    radius_m: float
    length_m: float

    def __post_init__(self) -> None:
        if not (np.isfinite(self.radius_m) and self.radius_m > 0):
            raise ValueError(f"tool capsule radius must be positive, not {self.radius_m:g} m")
        if not (np.isfinite(self.length_m) and self.length_m >= 0):
            raise ValueError(f"tool capsule length must not be negative, not {self.length_m:g} m")

    def as_dict(self) -> dict[str, float]:
        return {"radius_m": float(self.radius_m), "length_m": float(self.length_m)}


@dataclass(frozen=True)
class Joint:
    """One revolute joint and the link (body) it moves."""

    name: str
    xyz: np.ndarray            # origin of K_i in K_{i-1} [m]
    rotation: np.ndarray       # fixed rotation of K_i relative to K_{i-1} (3, 3)
    axis: str                  # 'x', 'y' or 'z' of K_i
    q_min: float               # [rad]
    q_max: float               # [rad]
    qd_max: float              # [rad/s]
    qdd_max: float             # [rad/s^2]
    tau_max: float             # [N m]
    gear_ratio: float          # i_G [-]
    torque_constant: float     # motor side k [N m / A]
    rotor_inertia: float       # reflected i_G^2 C_M [kg m^2]
    viscous_friction: float    # r_v [N m s / rad]
    coulomb_friction: float    # r_c [N m]
    mass: float                # [kg]
    com: np.ndarray            # centre of mass in K_i [m]
    inertia_com: np.ndarray    # (3, 3) inertia about the centre of mass, K_i axes [kg m^2]
    collision: tuple[Capsule, ...]


@dataclass(frozen=True)
class RobotSpec:
    """Everything urident knows about one robot model, in SI units."""

    name: str
    description: str
    generation: str                     # 'cb3' or 'e-series'
    controller_rate_hz: float
    controller_version: tuple[int, ...]
    gravity: np.ndarray                 # (3,) in the base frame [m/s^2]
    joints: tuple[Joint, ...]
    tool_xyz: np.ndarray
    tool_rotation: np.ndarray
    base_collision: tuple[Capsule, ...]
    allowed_contacts: frozenset[frozenset[str]]
    dh: dict[str, np.ndarray]
    source: Path
    model: str = ""                     # arm model as UR names it ("UR5e"); the dashboard drops the "e"
    reach_m: float | None = None        # datasheet reach [m]
    payload_kg: float | None = None     # datasheet payload class [kg]
    nominal: frozenset[str] = frozenset()  # NOMINAL_KEYS whose values are approximations
    arrays: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    tool: ToolCapsule | None = None     # a mounted tool's capsule, checked as the link "tool"

    def __post_init__(self) -> None:
        def stack(attr: str) -> np.ndarray:
            values = np.array([getattr(j, attr) for j in self.joints], dtype=float)
            values.setflags(write=False)
            return values

        for attr in ("q_min", "q_max", "qd_max", "qdd_max", "tau_max", "gear_ratio",
                     "torque_constant", "rotor_inertia", "viscous_friction", "coulomb_friction"):
            self.arrays[attr] = stack(attr)
        gains = self.arrays["gear_ratio"] * self.arrays["torque_constant"]
        gains.setflags(write=False)
        self.arrays["drive_gains"] = gains

    # Per-joint arrays (6,), read-only.
    q_min = property(lambda self: self.arrays["q_min"])
    q_max = property(lambda self: self.arrays["q_max"])
    qd_max = property(lambda self: self.arrays["qd_max"])
    qdd_max = property(lambda self: self.arrays["qdd_max"])
    tau_max = property(lambda self: self.arrays["tau_max"])
    gear_ratios = property(lambda self: self.arrays["gear_ratio"])
    torque_constants = property(lambda self: self.arrays["torque_constant"])
    drive_gains = property(lambda self: self.arrays["drive_gains"])  # i_G * k [N m / A]

    def with_tool(self, tool: ToolCapsule | None) -> "RobotSpec":
        """This robot with ``tool`` mounted on the flange (collision checks only)."""
        from dataclasses import replace

        return self if tool == self.tool else replace(self, arrays={}, tool=tool)

    @property
    def tool_collision(self) -> tuple[Capsule, ...]:
        """The tool's capsule in the last joint's frame K_6 (empty without a tool)."""
        if self.tool is None:
            return ()
        a = np.asarray(self.tool_xyz, dtype=float)
        b = a + np.asarray(self.tool_rotation, dtype=float) @ np.array([0.0, 0.0, self.tool.length_m])
        return (Capsule(a, b, float(self.tool.radius_m)),)

    def rated_payload_problem(self, mass_kg: float) -> str | None:
        """Why a load of ``mass_kg`` cannot be on this arm (above the datasheet's rated payload: a
        trajectory is never checked, nor run, for a load the arm is not rated for), or None."""
        if not math.isfinite(mass_kg):
            return f"payload mass must be finite, not {mass_kg}"
        if self.payload_kg is not None and mass_kg > self.payload_kg:
            return (f"payload {mass_kg:g} kg exceeds the rated payload of {self.model or self.name} "
                    f"({self.payload_kg:g} kg, robot file '{self.name}')")
        return None

    def check_rated_payload(self, mass_kg: float, where: str) -> None:
        """ConfigError (one line naming ``where``): :meth:`rated_payload_problem`."""
        problem = self.rated_payload_problem(mass_kg)
        if problem:
            raise ConfigError(f"{where}: {problem}")

    def tool_com_problem(self, com_m) -> str | None:
        """Why a tool's centre of mass [m, flange frame] is impossible, or None: not finite, or
        farther from the flange than the arm's datasheet reach (a value in mm, or a typo)."""
        com = np.asarray(com_m, dtype=float)
        if not np.all(np.isfinite(com)):
            return f"centre of mass must be finite, not {com.tolist()}"
        dist = float(np.linalg.norm(com))
        if self.reach_m is not None and dist > self.reach_m:
            return (f"centre of mass {dist:.4g} m from the flange, beyond the reach of "
                    f"{self.model or self.name} ({self.reach_m:g} m, robot file '{self.name}'): "
                    "metres, not millimetres?")
        return None

    def check_tool_com(self, com_m, where: str) -> None:
        """ConfigError (one line naming ``where``): :meth:`tool_com_problem`."""
        problem = self.tool_com_problem(com_m)
        if problem:
            raise ConfigError(f"{where}: {problem}")

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.joints)

    @property
    def dashboard_model(self) -> str:
        """What the dashboard's ``get robot model`` answers: e-Series controllers report the
        family name ("UR5" for a UR5e), UR20/UR30 and CB3 arms their own name."""
        model = self.model or self.name.upper()
        if self.generation == "e-series" and model[-1:] in ("e", "E"):
            return model[:-1]
        return model

    def nominal_note(self, keys: Iterable[str] | None = None) -> str | None:
        """One line naming this robot's nominal values among ``keys`` (default: all), or None."""
        marked = [k for k in NOMINAL_KEYS if k in self.nominal and (keys is None or k in keys)]
        if not marked:
            return None
        return (f"robot file '{self.name}': nominal values, not manufacturer data: "
                f"{', '.join(NOMINAL_KEYS[k] for k in marked)}")

    @property
    def nominal_params(self) -> np.ndarray:
        """The paper's 78-vector (eq. 39-40) of this robot's nominal parameters."""
        return standard_from_links(self)


def available_robots() -> list[str]:
    return sorted(p.stem for p in ROBOTS_DIR.glob("*.yaml"))


def robot_path(name_or_path: str | Path) -> Path | None:
    """The robot file ``name_or_path`` names when it is a path (ends in .yaml/.yml or holds a
    "/"), None when it is a robot's name."""
    text = str(name_or_path)
    return Path(text) if text.endswith((".yaml", ".yml")) or "/" in text else None


def load_robot(name_or_path: str | Path) -> RobotSpec:
    """Load a robot by name (``ur5e``, …: :func:`available_robots`) or from a YAML file path."""
    text = str(name_or_path)
    path = robot_path(text)  # missing, a directory, unreadable: load_yaml names the file
    if path is None:
        path = ROBOTS_DIR / f"{text.lower()}.yaml"
        if not path.is_file():
            raise UnknownRobotError(
                f"unknown robot '{text}'; available robots: {', '.join(available_robots())} "
                f"(or give the path of a robot file)", robot=text, available=tuple(available_robots()))
    return _parse(path)


def _parse(path: Path) -> RobotSpec:
    data = load_yaml(path, "robot file")
    reader = _Reader(path)
    reader.mapping(data, "", "a mapping at the top level")
    reader.keys(data, _TOP_KEYS, "")
    joints_data = reader.get(data, "joints", list)
    if len(joints_data) != N_JOINTS:
        raise reader.fail("joints", f"must list {N_JOINTS} joints, found {len(joints_data)}")
    joints = tuple(_parse_joint(reader, jd, f"joints[{i}]") for i, jd in enumerate(joints_data))
    generation = reader.get(data, "generation", str)
    if generation not in ("cb3", "e-series"):
        raise reader.fail("generation", f"must be 'cb3' or 'e-series', not {shown(generation)!r}")
    version_text = str(reader.get(data, "controller_version", (str, int, float)))
    try:
        version = tuple(int(v) for v in version_text.split("."))
    except ValueError:
        raise reader.fail("controller_version", "must look like 5.11.0") from None
    tool = reader.get(data, "tool", dict)
    reader.keys(tool, {"xyz", "rpy"}, "tool")
    names = [j.name for j in joints]
    allowed = []
    contacts = data.get("allowed_contacts", []) or []
    if not isinstance(contacts, list):
        raise reader.fail("allowed_contacts", "must be a list of pairs of joint names")
    for k, pair in enumerate(contacts):
        if (not isinstance(pair, list) or len(pair) != 2
                or not all(isinstance(n, str) and n in names + ["base"] for n in pair)):
            raise reader.fail(f"allowed_contacts[{k}]", "must be a pair of joint names")
        allowed.append(frozenset(pair))
    dh = reader.get(data, "dh", dict)
    reader.keys(dh, {"d", "a", "alpha"}, "dh")
    rate = float(reader.number(data, "controller_rate_hz", "", positive=True))
    nominal = data.get("nominal", []) or []
    if not isinstance(nominal, list) or any(not isinstance(k, str) or k not in NOMINAL_KEYS for k in nominal):
        raise reader.fail("nominal", f"must be a list of per-joint keys from: {', '.join(NOMINAL_KEYS)}")
    model = data.get("model", "")
    if not isinstance(model, str):
        raise reader.fail("model", "must be a string such as UR5e")
    optional = {k: float(reader.number(data, k, "", positive=True)) if k in data else None
                for k in ("reach_m", "payload_kg")}
    return RobotSpec(
        name=reader.get(data, "name", str),
        description=str(data.get("description", "")),
        generation=generation,
        controller_rate_hz=rate,
        controller_version=version,
        gravity=reader.vector(data, "gravity", "", 3),
        joints=joints,
        tool_xyz=reader.vector(tool, "xyz", "tool", 3),
        tool_rotation=rpy_to_matrix(reader.vector(tool, "rpy", "tool", 3)),
        base_collision=tuple(_parse_capsules(reader, data.get("base_collision", []), "base_collision")),
        allowed_contacts=frozenset(allowed),
        dh={k: reader.vector(dh, k, "dh", N_JOINTS) for k in ("d", "a", "alpha")},
        source=path,
        model=model,
        nominal=frozenset(nominal),
        **optional,
    )


def _parse_joint(reader: "_Reader", jd: Any, where: str) -> Joint:
    reader.mapping(jd, where)
    reader.keys(jd, _JOINT_KEYS, where)
    axis = reader.get(jd, "axis", str, where)
    if axis not in ("x", "y", "z"):
        raise reader.fail(f"{where}.axis", f"must be x, y or z, not {shown(axis)!r}")
    limits = reader.vector(jd, "position_limits", where, 2)
    if not limits[0] < limits[1]:
        raise reader.fail(f"{where}.position_limits", "must be [lower, upper] with lower < upper")
    link = reader.get(jd, "link", dict, where)
    lw = f"{where}.link"
    reader.keys(link, _LINK_KEYS, lw)
    inertia_com = inertia_matrix(reader.vector(link, "inertia_com", lw, 6), "ur")
    problem = inertia_problem(inertia_com)
    if problem:
        raise reader.fail(f"{lw}.inertia_com", problem)
    num = lambda key, **kw: float(reader.number(jd, key, where, **kw))  # noqa: E731
    return Joint(
        name=reader.get(jd, "name", str, where),
        xyz=reader.vector(jd, "xyz", where, 3),
        rotation=rpy_to_matrix(reader.vector(jd, "rpy", where, 3)),
        axis=axis,
        q_min=float(limits[0]), q_max=float(limits[1]),
        qd_max=num("velocity_limit", positive=True),
        qdd_max=num("acceleration_limit", positive=True),
        tau_max=num("torque_limit", positive=True),
        gear_ratio=num("gear_ratio", positive=True),
        torque_constant=num("torque_constant", positive=True),
        rotor_inertia=num("rotor_inertia", nonnegative=True),
        viscous_friction=num("viscous_friction", nonnegative=True),
        coulomb_friction=num("coulomb_friction", nonnegative=True),
        mass=float(reader.number(link, "mass", lw, positive=True)),
        com=reader.vector(link, "com", lw, 3),
        inertia_com=inertia_com,
        collision=tuple(_parse_capsules(reader, link.get("collision", []), f"{lw}.collision")),
    )


def _parse_capsules(reader: "_Reader", items: Any, where: str) -> list[Capsule]:
    if not isinstance(items, list):
        raise reader.fail(where, "must be a list of capsules")
    capsules = []
    for k, item in enumerate(items):
        w = f"{where}[{k}]"
        if not isinstance(item, dict):
            raise reader.fail(w, "must be a mapping with a, b, radius")
        reader.keys(item, _CAPSULE_KEYS, w)
        capsules.append(Capsule(reader.vector(item, "a", w, 3), reader.vector(item, "b", w, 3),
                                float(reader.number(item, "radius", w, positive=True))))
    return capsules


class _Reader(Fields):
    """:class:`~urident.yamlio.Fields` with read-only vectors, as the spec's arrays are."""

    def __init__(self, path: Path):
        super().__init__(path)
        self.path = path

    def vector(self, mapping: dict, key: str, where: str, size: int) -> np.ndarray:
        array = self.array(mapping, key, where, (size,))
        array.setflags(write=False)
        return array


def inertia_problem(inertia: np.ndarray, definite: bool = True) -> str | None:
    """Why a (3, 3) inertia about the centre of mass is physically impossible, or None: it must be
    symmetric positive definite (``definite`` False: semidefinite, a point mass's zero allowed) and
    its principal moments must satisfy the triangle inequality (each at most the sum of the other
    two, as for any real mass distribution). Robot files and payloads (files, trajectories) use it."""
    moments = np.linalg.eigvalsh(inertia)
    scale = max(float(np.abs(moments).max()), 1e-300)
    if not np.all(np.isfinite(moments)):
        return "must be finite"
    if definite and moments.min() <= 1e-12 * scale:
        return (f"is not positive definite (principal moments "
                f"{', '.join(f'{m:.4g}' for m in moments)} kg m^2)")
    if not definite and moments.min() < -1e-9 * scale:
        return (f"is not positive semidefinite (principal moments "
                f"{', '.join(f'{m:.4g}' for m in moments)} kg m^2)")
    a, b, c = moments
    if c > a + b + 1e-9 * scale:
        return (f"violates the triangle inequality: principal moment {c:.4g} > {a:.4g} + {b:.4g} "
                f"kg m^2 (no mass distribution has it)")
    return None


def rpy_to_matrix(rpy: np.ndarray) -> np.ndarray:
    """Rotation Rz(yaw)·Ry(pitch)·Rx(roll), the URDF convention."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    m = rz @ ry @ rx
    m[np.abs(m) < 1e-15] = 0.0
    return m
