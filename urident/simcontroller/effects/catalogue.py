"""The catalogue: every effect by its stable snake_case name (part of the public interface: the
gap diagnosis reports these names and the documentation lists them: docs/concepts/gap-diagnosis.md)."""

from __future__ import annotations

from dataclasses import dataclass

from urident.simcontroller.effects.base import Effect
from urident.simcontroller.effects.dynamics import JointElasticity, PayloadError
from urident.simcontroller.effects.friction import (AsymmetricCoulomb, LoadFriction, NeighbourLoadFriction,
                                                     PositionRipple, QuadraticViscous, Stribeck, ThermalDrift)
from urident.simcontroller.effects.params import Param
from urident.simcontroller.effects.sensor import CurrentDelay, CurrentLag, CurrentOffset, TorqueConstantError

#: Effect classes in catalogue (listing) order.
EFFECT_CLASSES: tuple[type[Effect], ...] = (
    Stribeck,
    LoadFriction,
    ThermalDrift,
    PositionRipple,
    CurrentDelay,
    TorqueConstantError,
    CurrentOffset,
    PayloadError,
    JointElasticity,
    QuadraticViscous,
    NeighbourLoadFriction,
    AsymmetricCoulomb,
    CurrentLag,
)
EFFECTS: dict[str, type[Effect]] = {cls.name: cls for cls in EFFECT_CLASSES}
EFFECT_NAMES: tuple[str, ...] = tuple(EFFECTS)

#: Order in which an effect set applies its effects: the link-side payload first (the gear and
#: the spring carry it), then friction, the joint spring last among torques; on the current, the
#: delay, the lag (both act on the drive's current with its noise), the gain and the offset (the
#: offset is added to the reported value).
APPLY_ORDER: tuple[str, ...] = (
    "payload_error", "stribeck", "load_friction", "thermal_drift", "quadratic_viscous", "neighbour_load_friction",
    "asymmetric_coulomb", "position_ripple",
    "joint_elasticity", "current_delay", "current_lag", "torque_constant_error", "current_offset",
)


@dataclass(frozen=True)
class CatalogueEntry:
    name: str
    summary: str
    details: str
    hook: str  # "torque" or "current"
    stateful: bool
    params: tuple[Param, ...]

    def format(self) -> str:
        """Multi-line description: name, summary, model, parameters with defaults."""
        kind = "stateful, " if self.stateful else ""
        lines = [f"{self.name} ({kind}{self.hook}): {self.summary}", f"    {self.details}"]
        lines += [f"    {p.describe()}" for p in self.params]
        return "\n".join(lines)


def catalogue() -> list[CatalogueEntry]:
    """Every effect with its one-line summary, model and parameters, in catalogue order."""
    return [CatalogueEntry(c.name, c.summary, c.details, c.hook, c.stateful, c.params)
            for c in EFFECT_CLASSES]


def format_catalogue() -> str:
    return "\n".join(entry.format() for entry in catalogue())
