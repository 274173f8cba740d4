"""What the joint-space square says: its title, what the other joints are held at, the 2-link arm's branch names.

The square draws two link headings against each other; on an arm of more than two links the arrows are the
denoiser's at poses whose other joints are the highlighted sample's at the step shown, which the view must
say, or the arrows read as the whole story. On a 2-link arm the target's two solutions are the two branches,
elbow up and elbow down, named where they are drawn. No viser here.
"""

from __future__ import annotations

import math

import numpy as np

JOINT_SPACE_HINT = (
    "Beside the arm, a square of two link angles (each link's heading to the +x axis; −π and π meet at the edges). "
    "Dots: the K samples at the step shown. Purple arrows: for a grid of poses taken as x_t, where the network's "
    "guess x̂0 lies (x_t → x̂0). On a 2-link arm the red ✕ are the target's two exact solutions, elbow up and elbow "
    "down; on more links the solutions form a continuum, so dark ✕ mark the final samples instead, and the other "
    "links are held at the highlighted sample's angles."
)


def joint_space_title(first: str, second: str) -> str:
    """The square's title: which angles, and what the arrows are."""
    return f"Joint space: link angles {first} (→) and {second} (↑); arrows: x_t → the network's guess x̂0"


def held_text(names: tuple[str, ...], joints: tuple[int, int], headings) -> str:
    """The line under the title on an arm of more than two links: the other joints' values, in degrees.

    `names` every joint's label (θ1 .. θN), `joints` the pair shown, `headings` (N,) the highlighted sample's.
    """
    headings = np.asarray(headings, dtype=np.float64)
    if len(names) != len(headings):
        raise ValueError(f"headings: expected {len(names)} angles, one per joint, got {len(headings)}")
    others = [index for index in range(len(names)) if index not in joints]
    if not others:
        return ""
    values = ", ".join(f"{names[index]} = {math.degrees(float(headings[index])):.0f}°" for index in others)
    return f"arrows with {values} (the blue sample's, at the step shown)"


def branch_name(lengths, headings) -> str:
    """A 2-link pose's branch: "elbow up" when its elbow lies left of the line from the base to its tip (for a
    target ahead, above it), "elbow down" when right. `headings` (2,) absolute, as the solution set gives them."""
    first, second = (float(value) for value in headings)
    l1, l2 = (float(length) for length in lengths)
    elbow = np.array([l1 * math.cos(first), l1 * math.sin(first)])
    tip = elbow + np.array([l2 * math.cos(second), l2 * math.sin(second)])
    side = tip[0] * elbow[1] - tip[1] * elbow[0]  # z of tip × elbow: positive when the elbow is counterclockwise
    return "elbow up" if side > 0 else "elbow down"
