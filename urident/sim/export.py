"""``urident export``'s work: identified parameters (or the robot file's nominal values) written as
a simulator model, MJCF (:mod:`urident.sim.mjcf`) or URDF (:mod:`urident.ident.urdf`), with the
identified terms the format cannot express in the file's top comment and in the result
(:class:`ExportedModel`), each with its share of a validation torque when validation recordings
are given."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from urident.errors import ConfigError

FORMATS = ("mjcf", "urdf")


@dataclass(frozen=True)
class ExportedModel:
    """A model file written: ``notes`` its top comment, ``terms`` the identified terms the format
    cannot express (:class:`urident.sim.terms.Term`; None for the robot file's nominal values)."""

    path: str | Path            # as given (the file written)
    fmt: str
    robot: str
    name: str
    notes: tuple[str, ...]
    terms: tuple | None

    def lines(self) -> list[str]:
        """What ``urident export`` prints for the file."""
        out = [f"wrote {self.path} ({self.fmt.upper()})"]
        if self.terms is not None:
            out += [f"  {t.line()}" for t in self.terms] or ["  every identified term is expressed"]
        return out

    def to_dict(self) -> dict:
        terms = None if self.terms is None else [
            {"kind": t.kind, "description": t.description, "joints": [j + 1 for j in t.joints],
             "share_pct": None if t.share_pct is None else [float(v) for v in t.share_pct]} for t in self.terms]
        return {"path": str(self.path), "format": self.fmt, "robot": self.robot, "name": self.name,
                "notes": list(self.notes), "not_expressed": terms}

    def to_json(self, indent: int | None = 2) -> str:
        return json.dumps(self.to_dict(), indent=indent)


def exportable(params, spec, label: str) -> None:
    """ConfigError (naming ``label``) unless ``params`` (an IdentifiedModel) is ``spec``'s and has a
    physically consistent estimate a simulator can take."""
    from urident.ident.identify import check_compatible
    from urident.ident.urdf import check_exportable

    if params.robot != spec.name:
        raise ConfigError(f"{label}: parameters are for robot {params.robot!r}, not {spec.name!r}")
    check_compatible(params, spec, label)
    if params.standard is None:
        raise ConfigError(f"{label}: no physically consistent estimate (standard_parameters is null): "
                          "identify with --method consistent or all")
    try:
        check_exportable(params.standard, "export")
    except ConfigError as exc:
        raise ConfigError(f"{label}: {exc}") from None


def _payload_note(payload, payload_label: str | None) -> list[str]:
    if payload is None:
        return []
    return [f"payload {payload_label} on the flange (body/link 'payload'): {payload.describe()}"]


def _write(fmt: str, spec, standard, out, name, notes, overwrite, payload, friction_eps=None) -> Path:
    from urident.ident.urdf import write_urdf
    from urident.sim.mjcf import write_mjcf

    if fmt not in FORMATS:
        raise ConfigError(f"export format {fmt!r} unknown (known: {', '.join(FORMATS)})")
    if fmt == "urdf":
        return write_urdf(spec, standard, out, name=name, notes=notes, overwrite=overwrite, payload=payload)
    kwargs = {} if friction_eps is None else {"friction_eps": friction_eps}
    return write_mjcf(spec, standard, out, name=name, notes=notes, overwrite=overwrite, payload=payload, **kwargs)


def export_identified(params, spec, out: str | Path, fmt: str, *, label: str, name: str | None = None,
                      payload=None, payload_label: str | None = None, valid_recordings: Sequence = (),
                      valid_labels: Sequence[str] = (), overwrite: bool = False) -> ExportedModel:
    """Write ``params``' physically consistent estimate (an IdentifiedModel, named ``label`` in the
    notes and errors) as a ``fmt`` model at ``out``; with ``valid_recordings`` each inexpressible
    term's share of their measured torque."""
    from urident.ident import predict_recordings
    from urident.sim.terms import inexpressible_terms

    exportable(params, spec, label)
    data = None
    if valid_recordings:
        data = predict_recordings(params, list(valid_recordings), spec, payload=payload).data
    header = [f"exported by urident from {label} (robot {spec.name}, method {params.method}, "
              f"Coulomb model {params.model.coulomb_text()}, tanh eps {params.model.friction_eps:g} rad/s)"]
    header += _payload_note(payload, payload_label)
    if data is not None:
        header.append("shares: RMS of the term's torque / RMS of the measured torque on " + ", ".join(valid_labels))
    terms = inexpressible_terms(params, spec, fmt, data)
    notes = header + [t.line() for t in terms] + ([] if terms else ["every identified term is expressed"])
    _write(fmt, spec, params.standard, out, name, notes, overwrite, payload,
           params.model.friction_eps if fmt == "mjcf" else None)
    return ExportedModel(out, fmt, spec.name, name or f"{spec.name}_identified", tuple(notes), tuple(terms))


def export_nominal(spec, out: str | Path, fmt: str, *, name: str | None = None, payload=None,
                   payload_label: str | None = None, overwrite: bool = False) -> ExportedModel:
    """Write the robot file's nominal values as a ``fmt`` model at ``out``."""
    notes = [f"the robot file {spec.source.name}'s nominal values, exported by urident"]
    note = spec.nominal_note()
    if note:
        notes.append(note)
    notes += _payload_note(payload, payload_label)
    name = name or f"{spec.name}_nominal"
    _write(fmt, spec, spec.nominal_params, out, name, notes, overwrite, payload)
    return ExportedModel(out, fmt, spec.name, name, tuple(notes), None)
