"""``urident drive-gains`` as a library step: the six joint drive gains i_G·k [N·m/A] from runs
without and with a known load (:func:`urident.ident.torque.estimate_drive_gains`), the joints the
runs do not calibrate kept at the robot file's value, and the report the command prints."""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from urident.errors import ConfigError

METHOD = ("joint least squares of the arm's base parameters, a constant torque per joint and six gains on both runs (payload "
          "torque known, point mass unless an inertia is given), refined by two instrumental-"
          "variable iterations (instruments: the currents the first fit predicts)")

#: A joint counts as calibrated when its gain's relative σ is at most this [%]: the load's torque
#: on it is well above the noise (a load on the flange axis gives joint 6 none, for one).
CALIBRATED_PCT = 1.0


@dataclass(frozen=True)
class DriveGainCalibration:
    """Drive gains [N·m/A] (6,) with their σ; ``estimated`` is what the runs gave, ``gains`` what
    is written (a joint in ``kept`` has the robot file's value: not calibrated, and its estimate
    is no drive's)."""

    robot: str
    gains: np.ndarray
    estimated: np.ndarray
    sigma: np.ndarray
    robot_file_gains: np.ndarray
    calibrated: tuple[bool, ...]
    kept: tuple[int, ...]              # joints (0-based) written with the robot file's gain
    without: tuple[str, ...]
    with_: tuple[str, ...]
    payload_mass_kg: float
    payload_com_m: np.ndarray
    method: str = METHOD

    @property
    def relative_sigma_pct(self) -> np.ndarray:
        return 100 * self.sigma / np.abs(self.estimated)

    def _data(self) -> dict:
        return {"without": list(self.without), "with": list(self.with_), "payload_mass_kg": self.payload_mass_kg,
                "payload_com_m": [float(v) for v in self.payload_com_m],
                "robot_file_gains": [float(g) for g in self.robot_file_gains],
                "robot_file_gain_kept": [j + 1 for j in self.kept]}

    def save(self, path, overwrite: bool = False) -> None:
        """Write GAINS.yaml (read by every ``--drive-gains``)."""
        from urident.ident.gains_file import save_gains

        save_gains(path, self.robot, self.gains, self.sigma, self.method, self._data(), overwrite=overwrite)

    def to_dict(self) -> dict:
        return {"drive_gains": [float(g) for g in self.gains], "sigma": [float(s) for s in self.sigma],
                "method": self.method, "robot": self.robot, **self._data(), "calibrated": list(self.calibrated)}

    def to_json(self, indent: int | None = 2) -> str:
        return json.dumps(self.to_dict(), indent=indent)

    def text(self) -> str:
        """The report ``urident drive-gains`` prints."""
        lines = [f"drive gains on {self.robot} [N·m/A] (robot file: "
                 + ", ".join(f"{g:.4g}" for g in self.robot_file_gains) + ")"]
        for j, (g, s, r, g0) in enumerate(zip(self.estimated, self.sigma, self.relative_sigma_pct,
                                              self.robot_file_gains)):
            verdict = "" if self.calibrated[j] else f"  NOT calibrated (σ > {CALIBRATED_PCT:g} %): keep another value"
            if j in self.kept:
                verdict = (f"  NOT calibrated (σ > {CALIBRATED_PCT:g} %) and no drive's gain: the robot file's "
                           f"{g0:.4g} written")
            lines.append(f"  joint {j + 1}: {g:9.4f} ± {s:.4f} ({r:.2f} %), {100 * (g / g0 - 1):+.1f} % vs the "
                         f"robot file{verdict}")
        lines.append(f"  method: {self.method}")
        return "\n".join(lines)


def calibrate_gains(spec, without: Sequence[tuple[str, object]], with_: Sequence[tuple[str, object]],
                    payload, *, reduced: bool = False) -> DriveGainCalibration:
    """Drive gains of ``spec`` from ``(name, Recording)`` runs without and with ``payload`` (a
    :class:`urident.model.payload.Payload` of known mass and centre of mass) on the flange. The
    recordings' torque signal must be the motor current (ConfigError otherwise)."""
    from urident.ident import PreprocessConfig, prepare
    from urident.ident.payload import check_wrist_motion
    from urident.ident.torque import DriveGainError, estimate_drive_gains, gain_problem

    loaded_names = " ".join(name for name, _ in with_)
    runs = []
    for group in (without, with_):
        data = prepare([rec for _, rec in group], spec, PreprocessConfig(), np.ones(6))   # tau = current [A]
        runs.append((data.q, data.qd, data.qdd, data.tau))
    check_wrist_motion(runs[1][0], "--with logs")
    try:
        est = estimate_drive_gains(spec, runs[0], runs[1], payload.body_params(spec), reduced=reduced, offset=True)
    except DriveGainError as exc:
        hint = ": are --with and --without swapped?" if exc.swapped else ""
        raise ConfigError(f"--with {loaded_names}: {exc}{hint}") from None
    calibrated = tuple(bool(r <= CALIBRATED_PCT) for r in 100 * est.sigma / np.abs(est.gains))
    kept = []
    for j in range(6):
        problem = gain_problem(est.gains, spec.drive_gains, joints=[j])
        if problem and calibrated[j]:
            raise ConfigError(f"--with {loaded_names}: {problem}: are --with and --without swapped, the load and "
                              "its --payload-mass/--payload-com as given?")
        if problem:
            kept.append(j)
    gains = np.array([spec.drive_gains[j] if j in kept else g for j, g in enumerate(est.gains)])
    return DriveGainCalibration(spec.name, gains, np.asarray(est.gains, float), np.asarray(est.sigma, float),
                                np.asarray(spec.drive_gains, float), calibrated, tuple(kept),
                                tuple(name for name, _ in without), tuple(name for name, _ in with_),
                                float(payload.mass_kg), np.asarray(payload.com_m, float))
