"""The Constraints folder's lock fields: each joint's value in units a person reads, within its limits.

A revolute joint is typed in degrees (a planar arm's heading too), a prismatic one in mm; the
field's range is the joint's limits. A joint without limits (a continuous joint, or a planar
heading) takes any angle and is wrapped into (-180, 180] (typed as
degrees, never read as radians). No viser here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class LockField:
    """How one joint's lock is typed: its name, unit, and range in that unit (None: any value, wrapped)."""

    name: str
    unit: str  # "°" or "mm"
    scale: float  # the joint's value (rad or m) per unit typed
    low: float | None  # the field's range in its unit; None for a joint without limits
    high: float | None

    @property
    def label(self) -> str:
        return f"{self.name} ({self.unit})"

    @property
    def wraps(self) -> bool:
        return self.low is None

    @property
    def initial(self) -> float:
        """The field's first value: the middle of the range (0 for a joint that wraps)."""
        return 0.0 if self.wraps else round((self.low + self.high) / 2, 1)

    def joint_value(self, typed: float) -> tuple[float, str | None]:
        """The joint's value (rad or m) for `typed`, and a note when it was wrapped or clamped into the range."""
        typed = float(typed)
        if not math.isfinite(typed):
            raise ValueError(f"{self.label}: expected a finite number, got {typed}")
        if self.wraps:
            wrapped = -((-typed + 180.0) % 360.0 - 180.0)  # into (-180, 180]
            note = (
                None if math.isclose(wrapped, typed) else f"{self.name} {typed:g}{self.unit} is {wrapped:g}{self.unit}"
            )
            note = None if note is None else note + " (wrapped)"
            return math.radians(wrapped), note
        clamped = min(max(typed, self.low), self.high)
        note = None
        if clamped != typed:
            note = f"{self.name} {typed:g}{self.unit} is outside [{self.low:g}, {self.high:g}]: locked at {clamped:g}"
        return clamped * self.scale, note


def lock_fields(arm) -> list[LockField]:
    """One field per joint of `arm`: a planar arm's headings (any angle), a chain's joints by type and limits."""
    if arm.kind == "planar":
        return [LockField(f"θ{index + 1}", "°", math.pi / 180, None, None) for index in range(arm.num_joints)]
    limits = arm.joint_limits.tolist()
    fields = []
    for name, kind, (low, high) in zip(arm.joint_names, arm.joint_types, limits, strict=True):
        if kind == "prismatic":
            fields.append(LockField(name, "mm", 1e-3, round(1000 * low, 1), round(1000 * high, 1)))
        elif kind == "continuous" or not (math.isfinite(low) and math.isfinite(high)):
            fields.append(LockField(name, "°", math.pi / 180, None, None))
        else:
            degrees = round(math.degrees(low), 2), round(math.degrees(high), 2)
            fields.append(LockField(name, "°", math.pi / 180, *degrees))
    return fields
