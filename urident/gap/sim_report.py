"""``gap --sim``'s whole analysis and report: the diagnosis of a user's simulator model
(:func:`urident.gap.sim_baseline.diagnose_sim`), which findings its format can express and with
which value, the drive terms not found and their detection limits, the shrink the expressible
findings predict and, with a path to write to, the corrected model measured by the simulator
itself. :func:`diagnose_sim_model` returns a :class:`SimGapReport`: ``lines()`` is what the command
prints, ``to_dict()``/``to_json()`` what its ``--json-out`` writes.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

#: --max-effects default with --sim: a downloaded model lacks three drive terms on six joints (18),
#: and what the data show beyond them (offsets, delay, link corrections) takes a few more
SIM_MAX_EFFECTS = 30
#: the column each drive term's detection limit is stated at
_COLUMN = {"armature": "q̈", "damping": "q̇", "frictionloss": "tanh(q̇/ε)"}


def _key(finding) -> tuple:
    return finding.effect, None if finding.effect == "payload_error" else finding.joint - 1


def _shrink(before: np.ndarray, after: np.ndarray) -> np.ndarray:
    return 100.0 * (1 - after / np.where(before > 0, before, np.inf))


@dataclass(frozen=True)
class SimFinding:
    """A finding of the diagnosis as the simulator model takes it: ``final_magnitude`` the value of
    all chosen corrections fitted together, ``written_magnitude`` the value written (the
    expressible findings refitted without the rest; None when not written), ``inseparable`` the
    link inertia fields an armature value also holds."""

    effect: str
    joint: int
    expressible: bool
    shrink_pct: float
    final_magnitude: dict | None
    written_magnitude: dict | None
    inseparable: tuple[str, ...] = ()


@dataclass(frozen=True)
class SimCorrected:
    """The corrected model written and measured by its own simulator on the validation states."""

    path: Path
    fmt: str
    e_n: float
    rms_nm: np.ndarray                 # (6,)
    shrink_pct: np.ndarray             # (6,) of the baseline RMS
    before: object                     # DriveTerms of the model
    after: object                      # DriveTerms written
    link_mass_before_kg: tuple[float, ...]
    link_mass_after_kg: tuple[float, ...]

    def to_dict(self) -> dict:
        return {"e_n": float(self.e_n), "rms_nm": [float(v) for v in self.rms_nm], "path": str(self.path),
                "values": {**self.after.to_dict(), "link_mass_kg": list(self.link_mass_after_kg)}}

    def lines(self) -> list[str]:
        out = ["    written model, measured by " + ("MuJoCo" if self.fmt == "mjcf" else "Pinocchio") + "    "
               + " ".join(f"{v:6.1f}" for v in self.shrink_pct),
               "  written values (model → written), joints 1-6:"]
        for key, unit in (("armature", "kg·m²"), ("damping", "N·m·s/rad"), ("frictionloss", "N·m")):
            if self.fmt == "mjcf" or key != "armature":
                out.append(f"    {key + ' [' + unit + ']':28s} " + "  ".join(
                    f"{a:.4g}→{b:.4g}" for a, b in zip(self.before[key], self.after[key])))
        out.append(f"    {'link mass [kg]':28s} " + "  ".join(
            f"{a:.4g}→{b:.4g}" for a, b in zip(self.link_mass_before_kg, self.link_mass_after_kg)))
        out.append(f"wrote {self.path}")
        return out


@dataclass(frozen=True)
class SimGapReport:
    """The gap of a simulator model: ``result`` the diagnosis (a :class:`urident.gap.GapResult`),
    the model beside the robot file (``comparison``), per finding what the format takes, the drive
    terms not found (``limits``), the links not written (``unwritable``), the predicted shrink per
    joint [%] of the expressible findings (and of the inexpressible ones), and the corrected model
    when one was written."""

    result: object = field(repr=False)
    spec: object = field(repr=False)
    model: str                                   # the model file as given
    fmt: str
    joint_names: tuple[str, ...]
    comparison: object = field(repr=False)       # urident.sim.compare.ModelComparison
    findings: tuple[SimFinding, ...]
    limits: tuple = ()                           # DetectionLimit
    unwritable: tuple[str, ...] = ()
    predicted_rms_nm: np.ndarray = field(default_factory=lambda: np.zeros(6))
    predicted_shrink_pct: np.ndarray = field(default_factory=lambda: np.zeros(6))
    inexpressible_shrink_pct: np.ndarray | None = None
    corrected: SimCorrected | None = None
    predicted_residual: np.ndarray | None = field(default=None, repr=False)   # (N, 6) [N·m]

    @property
    def predicted_e_n(self) -> float:
        """e_N of the validation residual the expressible findings predict."""
        from urident.gap.results import e_n

        return float(e_n(self.predicted_residual))

    def to_dict(self) -> dict:
        """The document ``urident gap --sim --json-out`` writes (before :func:`json_safe`)."""
        doc = self.result.as_dict()
        doc["not_identified"] = [d.as_dict() for d in self.limits]
        rows = doc.get("findings", [])
        for fd, f in zip(rows, self.findings):
            fd["expressible"] = f.expressible
            fd["final_magnitude"] = f.final_magnitude
            if f.effect == "armature":
                fd["inseparable_link_inertia"] = list(f.inseparable)
        doc["baseline"]["sim_model"] = {"path": self.model, "format": self.fmt, "joints": list(self.joint_names),
                                        "against_robot_file": self.comparison.to_dict()}
        for fd, f in zip(rows, self.findings):
            fd["written_magnitude"] = f.written_magnitude
        doc["sim_predicted"] = {"e_n": self.predicted_e_n, "rms_nm": [float(v) for v in self.predicted_rms_nm]}
        if self.corrected is not None:
            doc["sim_corrected"] = self.corrected.to_dict()
        return doc

    def to_json(self, indent: int | None = 1) -> str:
        """The JSON text ``--json-out`` writes: no NaN, None or infinity (an absent quantity says why)."""
        from urident.gap.results import json_default, json_safe

        return json.dumps(json_safe(self.to_dict()), indent=indent, allow_nan=False, default=json_default)

    def lines(self) -> list[str]:
        """The report the command prints."""
        from urident.gap import format_report

        out = [format_report(self.result), "", *self.comparison.lines(self.spec, self.fmt), "",
               f"Simulator model {self.model} ({self.fmt.upper()}): which findings the format can express"]
        for f in self.findings:
            shown = ", ".join(f"{k} = {v:.4g}" for k, v in (f.final_magnitude or {}).items() if isinstance(v, float))
            out.append(f"  {f.effect:22s} joint {f.joint}  {'expressible' if f.expressible else 'NOT expressible':16s} "
                       f"{f.shrink_pct:5.1f} % shrink  {shown}")
            if f.effect == "armature" and f.inseparable:
                out.append(f"    (holds rotor inertia plus the error of link {f.joint}'s inertia "
                           f"{', '.join(f.inseparable)} about K_{f.joint}: they act alike on these states and in the "
                           "simulator, nothing tells them apart)")
        if self.limits:
            out.append("  not found: on these states, on top of the findings, a term below this is within the noise "
                       "(not identifiable, not shown absent):")
            for d in self.limits:
                out.append(f"  {d.effect:22s} joint {d.joint}  below about {d.limit:.3g} {d.unit} "
                           f"({d.below_nm:.3f} N·m at {_COLUMN[d.effect]} RMS {d.column_rms:.3g})")
        for name in self.unwritable:
            out.append(f"  {name}: not a real mass distribution (the inertia about the new centre of mass "
                       "would not be positive): not written")
        out += ["  shrink of the validation RMS per joint [%]:",
                "    expressible findings, predicted   " + " ".join(f"{v:6.1f}" for v in self.predicted_shrink_pct)]
        if self.inexpressible_shrink_pct is not None:
            out.append("    inexpressible findings, predicted "
                       + " ".join(f"{v:6.1f}" for v in self.inexpressible_shrink_pct))
        if self.corrected is not None:
            out += self.corrected.lines()
        return out


def diagnose_sim_model(sim, valid_recordings: Sequence, spec, *, model_label: str | None = None,
                       drive_gains=None, config=None, write_to: str | Path | None = None,
                       overwrite: bool = False, valid_labels: Sequence[str] = (),
                       joint_map: dict | None = None) -> SimGapReport:
    """The gap of ``sim`` (a :class:`urident.sim.models.SimModel`) on the validation recordings:
    the diagnosis, what the model's format takes of it and, with ``write_to``, the model written
    with every expressible finding (:func:`urident.sim.correct.write_corrected`; notes name the
    model and ``valid_labels``) and measured by its own simulator."""
    from urident.errors import ConfigError
    from urident.gap.results import rms
    from urident.gap.sim_baseline import (corrections, detection_limits, diagnose_sim, expressible,
                                          expressible_fit, link_inertia_columns, unwritable)
    from urident.sim.compare import compare_model
    from urident.sim.correct import unrealisable_links
    from urident.sim.models import load_sim_model, model_format

    fmt = sim.fmt
    label = str(sim.path) if model_label is None else str(model_label)
    if write_to is not None and model_format(write_to) != fmt:
        raise ConfigError(f"--write-sim {write_to}: must be {fmt.upper()} like --sim {label}")
    result = diagnose_sim(valid_recordings, spec, sim, drive_gains=drive_gains, config=config)
    states = result.valid.data.prepared
    comparison = compare_model(sim, spec, states.q, states.qd, states.qdd)
    final = {(c.effect, c.joint): c.magnitude(beta, spec) for c, beta in result.fit.coefficients().items()}
    r0 = result.valid.residual
    chosen, fit = expressible_fit(result)
    all_changes = corrections(result)
    bad = unwritable(chosen, set(unrealisable_links(sim, spec, all_changes)), all_changes)
    written = [c for c in chosen if c not in bad]
    if len(written) != len(chosen):
        fit = result.correction(written)
    predicted = r0 - fit.change(result.valid) if written else r0
    # the value written: the expressible findings refitted without the rest (the format's
    # equivalent, e.g. a frictionloss that also carries a Stribeck term's average), beside the
    # final joint fit's value of the term itself
    kept = {(c.effect, c.joint): c.magnitude(beta, spec) for c, beta in fit.coefficients().items()} if written else {}
    written_arm = corrections(result, written)["armature"] if written else np.zeros(6)
    for (effect, j), value in kept.items():
        if effect == "armature":      # with what the link corrections hand to it (off_armature)
            value["armature_kg_m2"] = float(written_arm[j])
    findings = tuple(SimFinding(f.effect, f.joint, expressible(fmt, f.effect), f.shrink_pct, final.get(_key(f)),
                                kept.get(_key(f)),
                                tuple(link_inertia_columns(spec, result.valid, f.joint - 1)[1])
                                if f.effect == "armature" else ())
                     for f in result.findings)
    inexpressible = [c for c in result.chosen() if not expressible(fmt, c.effect)]
    rest = None
    if inexpressible:
        rest = _shrink(rms(r0), rms(r0 - result.correction(inexpressible).change(result.valid)))
    corrected = None
    if write_to is not None:
        from urident.sim.correct import write_corrected

        notes = [f"corrected by urident gap from {label} on {', '.join(map(str, valid_labels))}"]
        notes += [f"not expressible here: {c.name}" for c in inexpressible]
        path = write_corrected(sim, spec, corrections(result, written), write_to, notes=notes, overwrite=overwrite)
        new = load_sim_model(path, spec, joint_map=joint_map)
        r1 = states.tau - new.predict(states.q, states.qd, states.qdd)
        from urident.gap.results import e_n

        corrected = SimCorrected(path, fmt, float(e_n(r1)), rms(r1), _shrink(rms(r0), rms(r1)), sim.drive(),
                                 new.drive(), tuple(comparison.link_mass_kg),
                                 tuple(compare_model(new, spec).link_mass_kg))
    return SimGapReport(result, spec, label, fmt, tuple(sim.joint_names), comparison, findings,
                        tuple(detection_limits(result)), tuple(c.name for c in bad), rms(predicted),
                        _shrink(rms(r0), rms(predicted)), rest, corrected, predicted)
