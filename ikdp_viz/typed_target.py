"""A target typed as numbers, in the panel or on the command line, and the numbers the panel shows for a target.

A planar arm's target is x, y. A robot's is its hand's position in metres and, for a pose
model, a rotation: typed as roll, pitch, yaw in degrees (the panel; the command line's
six numbers) or as a quaternion w, x, y, z (the command line's seven). A pose model given
a position alone keeps the rotation it had. No viser here (its small SO3 helper aside).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import viser.transforms as transforms


def rotation_wxyz(roll_pitch_yaw_degrees) -> np.ndarray:
    """(4,) unit quaternion w, x, y, z of a rotation given as roll, pitch, yaw in degrees (about x, then y, then z)."""
    roll, pitch, yaw = np.deg2rad(np.asarray(roll_pitch_yaw_degrees, dtype=np.float64))
    return np.asarray(transforms.SO3.from_rpy_radians(roll, pitch, yaw).wxyz, dtype=np.float64)


def roll_pitch_yaw_degrees(wxyz) -> np.ndarray:
    """(3,) roll, pitch, yaw in degrees of the unit quaternion `wxyz`."""
    angles = transforms.SO3(np.asarray(wxyz, dtype=np.float64)).as_rpy_radians()
    return np.rad2deg(np.array([angles.roll, angles.pitch, angles.yaw]))


def finite_numbers(values) -> np.ndarray:
    values = np.asarray(values, dtype=np.float64).reshape(-1)
    if not np.isfinite(values).all():
        raise ValueError(f"target: expected finite numbers, got {values.tolist()}")
    return values


def point_from_numbers(values) -> np.ndarray:
    """A planar arm's typed target: x, y (not yet pulled into the workspace). ValueError names what was expected."""
    values = finite_numbers(values)
    if values.size != 2:
        raise ValueError(f"target: a planar arm's target is x y, got {values.size} numbers")
    return values


def pose_from_numbers(values, *, target_dim: int, current: np.ndarray) -> np.ndarray:
    """A robot's typed target: x, y, z metres; then roll, pitch, yaw degrees (6 numbers) or w, x, y, z (7); a pose
    model given 3 numbers keeps `current`'s rotation. ValueError names what was expected."""
    values = finite_numbers(values)
    if target_dim == 3:
        if values.size != 3:
            raise ValueError(f"target: this robot model's target is a position x y z (m), got {values.size} numbers")
        return values
    if values.size == 3:
        return np.concatenate((values, np.asarray(current, dtype=np.float64)[3:7]))
    if values.size == 6:
        return np.concatenate((values[:3], rotation_wxyz(values[3:])))
    if values.size == 7:
        return values
    raise ValueError(
        "target: a robot's pose target is x y z (m), then roll pitch yaw (degrees) or w x y z; "
        f"got {values.size} numbers"
    )


# The Constraints folder's lock fields: each joint's value in units a person reads, within its limits.
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


def heading_lock_fields(arm) -> list[LockField]:
    """One field per link of a planar `arm`: its absolute heading, any angle."""
    return [LockField(f"θ{index + 1}", "°", math.pi / 180, None, None) for index in range(arm.num_joints)]


def joint_lock_fields(arm) -> list[LockField]:
    """One field per joint of a robot `arm`, by its type and limits."""
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
