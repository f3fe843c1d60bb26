"""``urident payload`` as a library step: a tool's ten parameters from loaded logs (and tares of
the same motion) on an identified arm, with the fit it achieved and the report the command prints.
The estimator itself is :func:`urident.ident.payload.estimate_payload`."""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from urident.errors import ConfigError
from urident.model.payload import PAYLOAD_FIELDS, Payload

#: Which controllers take the inertia (printed under the URScript line).
POLYSCOPE_NOTE = ("the inertia argument: UR's script manual for software 10.6 (PolyScope X; "
                  "manuals/EN/HTML/SW10_6/Content/prod-scriptmanual/G5/set_target_payload.htm) documents set_target_payload(m, cog, inertia=[0, 0, 0, 0, 0, 0], "
                  "transition_time=0), inertia about the centre of mass with flange axes, Ixx..Izz >= 0; "
                  "ur_rtde 1.6.5's control script sends set_target_payload(mass, cog, inertia) only to "
                  "e-Series controllers of software 5.10 or later (its lines tagged $5.10) and "
                  "set_payload(mass, cog), which takes no inertia, to older ones: on PolyScope 5 before "
                  "5.10 and on CB3 (3.x, no evidence found) use set_payload(m, [cx, cy, cz])")


@dataclass(frozen=True)
class PayloadIdentification:
    """A tool identified on an arm. ``payload``: the physically consistent estimate (what the
    payload file holds); ``least_squares``: the unconstrained one. RMS [N·m] per joint (6,) and
    the paper's e_N of the arm alone and with the payload, on the samples fitted."""

    robot: str
    payload: Payload
    least_squares: Payload
    n_samples: int
    e_n_arm_alone: float
    e_n_with_payload: float
    rms_nm_arm_alone: np.ndarray
    rms_nm_with_payload: np.ndarray
    drive_gains: np.ndarray
    drive_gains_given: bool
    params: str                      # the arm's parameters file
    logs: tuple[str, ...]
    unloaded_logs: tuple[str, ...] = ()
    n_tare_samples: int = 0          # samples of the tare runs (0: no tare)
    n_tared_samples: int = 0         # loaded samples the tare was subtracted from

    @property
    def mass_bound_kg(self) -> float | None:
        """The --mass-range bound the consistent mass sits on (the logs did not set it), or None."""
        return self.payload.info.get("mass_bound_kg")

    def fit(self) -> dict:
        """The ``fit`` section of the payload file and the JSON."""
        return {"n_samples": int(self.n_samples), "e_n_arm_alone": float(self.e_n_arm_alone),
                "e_n_with_payload": float(self.e_n_with_payload),
                "rms_nm_arm_alone": [float(v) for v in self.rms_nm_arm_alone],
                "rms_nm_with_payload": [float(v) for v in self.rms_nm_with_payload],
                "drive_gains": [float(g) for g in self.drive_gains], "params": self.params,
                "unloaded_logs": list(self.unloaded_logs)}

    def to_dict(self) -> dict:
        out = dict(_payload_dict(self.payload), method="consistent")
        out["least_squares"] = _payload_dict(self.least_squares)
        out["fit"] = self.fit()
        return out

    def to_json(self, indent: int | None = 2) -> str:
        return json.dumps(self.to_dict(), indent=indent)

    def save(self, path, overwrite: bool = False) -> None:
        """Write the payload file (``urident-payload``), the fit included."""
        from urident.ident.payload_file import save_payload

        save_payload(self.payload, path, overwrite=overwrite, fit=self.fit())

    def text(self) -> str:
        """The report ``urident payload`` prints."""
        est, ols = self.payload, self.least_squares
        bound = self.mass_bound_kg
        fixed = [n for n in PAYLOAD_FIELDS if n not in est.identifiable and not (bound is not None and n == "m")]
        tared = self.n_tare_samples > 0
        lines = [f"payload on {self.robot} from {len(self.logs)} log(s), {self.n_samples} samples, arm {self.params}"
                 + (f", tare: {len(self.unloaded_logs)} unloaded log(s) of {self.n_tare_samples} samples, "
                    f"subtracted sample by sample from {self.n_tared_samples} loaded samples (every error of "
                    "the arm model on that motion removed)" if tared else ""),
                 f"  least squares:        {ols.describe()}",
                 f"  physically consistent: {est.describe()}",
                 f"  sigma: mass {ols.sigma['mass_kg']:.4f} kg, centre of mass "
                 f"[{', '.join(_mm(v) for v in ols.sigma['com_m'])}] mm",
                 f"  identifiable: {', '.join(est.identifiable)}",
                 ("  not identifiable (fixed: first moments 0, inertia a point mass's): " + ", ".join(fixed))
                 if fixed else "  every parameter identifiable",
                 *([] if tared else
                   ["  (the inertia needs --unloaded, a run of the same trajectory without the tool: the arm "
                    "model's own last-body error is of the order of a tool's inertia)"]),
                 "  fit rms_nm arm alone   " + " ".join(f"{v:6.2f}" for v in self.rms_nm_arm_alone)
                 + f"  e_N {self.e_n_arm_alone:.4f}",
                 "  fit rms_nm with payload " + " ".join(f"{v:6.2f}" for v in self.rms_nm_with_payload)
                 + f"  e_N {self.e_n_with_payload:.4f}",
                 "  drive gains [N·m/A] " + ", ".join(f"{g:.4g}" for g in self.drive_gains)
                 + (" (given)" if self.drive_gains_given else " (the parameters file's)"),
                 *([est.urscript(), f"  ({POLYSCOPE_NOTE})"] if bound is None else
                   [f"  mass NOT identified: on the --mass-range bound {bound:g} kg (active: the bound, not the "
                    f"logs, sets it; least squares {ols.mass_kg:.4g} kg); no set_target_payload line: "
                    "widen --mass-range or leave it out"])]
        if self.e_n_with_payload > self.e_n_arm_alone:
            lines.insert(-1, f"  the payload makes the fit worse than the arm alone (e_N {self.e_n_with_payload:.4f} "
                             f"vs {self.e_n_arm_alone:.4f}): do the logs carry this tool?")
        return "\n".join(lines)


def fit_payload(arm, spec, loaded: Sequence[tuple[str, object]], tare: Sequence[tuple[str, object]] = (), *,
                mass_range=None, drive_gains=None, params_label: str = "",
                tare_labels: Sequence[str] | None = None,
                tare_wrist_labels: Sequence[str] | None = None) -> PayloadIdentification:
    """Identify the tool the ``loaded`` recordings carry on the identified ``arm`` (an
    :class:`urident.ident.IdentifiedModel` for ``spec``). ``loaded`` and ``tare`` are
    ``(name, Recording)`` pairs, the name (the log's path) naming it in errors and in the fit
    (``tare_labels``, ``tare_wrist_labels``: other names for the tares in the same-motion and the
    wrist-motion errors, e.g. with their rows and the flag that chose them); every tare must be the motion
    of a loaded log, and with tares every loaded log needs one (PayloadError otherwise).
    ``mass_range``: (low, high) [kg] for the consistent estimate; ``drive_gains``: six gains
    [N·m/A] instead of the parameters file's."""
    from urident.ident import predict_recordings
    from urident.ident.identify import check_compatible
    from urident.ident.payload import check_same_motion, check_wrist_motion, estimate_payload, since_first_row

    if arm.robot != spec.name:
        raise ConfigError(f"{params_label or 'parameters'}: parameters are for robot {arm.robot!r}, not {spec.name!r}")
    check_compatible(arm, spec, params_label or "parameters")
    if mass_range is not None:
        spec.check_rated_payload(mass_range[0], f"--mass-range {mass_range[0]:g},{mass_range[1]:g}")
    gains = None if drive_gains is None else np.asarray(drive_gains, dtype=float)
    recordings = [rec for _, rec in loaded]
    prediction = predict_recordings(arm, recordings, spec, drive_gains=gains)
    unloaded = None
    if tare:
        labels = list(tare_labels) if tare_labels is not None else [name for name, _ in tare]
        wrist = list(tare_wrist_labels) if tare_wrist_labels is not None else labels
        for label, (_, rec) in zip(wrist, tare):   # the clearer message first: a still wrist is no tare
            check_wrist_motion(rec.q, label)
        check_same_motion([(name, r.t, r.q) for name, r in loaded],
                          [(label, r.t, r.q) for label, (_, r) in zip(labels, tare)])
        tare_recs = [rec for _, rec in tare]
        unloaded = since_first_row(predict_recordings(arm, tare_recs, spec, drive_gains=gains), tare_recs)
    data = since_first_row(prediction, recordings) if unloaded is not None else prediction.data
    est = estimate_payload(arm, spec, data, mass_range, unloaded=unloaded)
    return PayloadIdentification(
        spec.name, est.consistent, est.ols, est.n_samples, float(est.train_e_n_arm), float(est.train_e_n),
        np.asarray(est.train_rms_arm, float), np.asarray(est.train_rms, float),
        np.asarray(prediction.data.drive_gains, float), gains is not None, params_label,
        tuple(label for label, _ in loaded), tuple(label for label, _ in tare),
        0 if unloaded is None else len(unloaded), int(est.ols.info.get("tared_samples", 0)) if unloaded is not None else 0)


def _mm(v: float) -> str:
    return "fixed" if v != v else f"{1000 * v:.1f}"


def _payload_dict(p: Payload) -> dict:
    from urident.ident.payload_file import to_dict

    d = to_dict(p)
    return {k: d[k] for k in ("mass_kg", "com_m", "inertia_kg_m2", "sigma", "identifiable", "urscript")}
