"""Where the camera stands: over a planar workspace, over it and its side views together, or before a robot.

Side views (the joint-space square, the comparison's second workspace) report the part of
the plane they cover as an `Extent`; `camera_over` frames the union of what is shown, so
one function, called by the drawing loop alone, moves the camera. No viser here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

Camera = tuple[tuple[float, float, float], tuple[float, float, float]]  # (position, look_at)
FRAMING = 1.55  # camera height over the half-width of what it frames (the planar view's top-down look)
VERTICAL_FOV = np.radians(75.0)  # viser's field of view, vertical: a window narrower than tall sees less across


@dataclass(frozen=True)
class Extent:
    """A box of the ground plane that a view draws in: x from `left` to `right`, y from `bottom` to `top`."""

    left: float
    right: float
    bottom: float
    top: float

    @classmethod
    def disc(cls, radius: float, x: float = 0.0) -> Extent:
        return cls(x - radius, x + radius, -radius, radius)


def camera_over(extents: list[Extent]) -> Camera:
    """(position, look_at) of a camera straight above the union of `extents`, all of it in view.

    +x to the right and +y up (a hair off the pole so "up" is defined). Framed by width, as the
    panel's column leaves the view wider than tall.
    """
    left, right = min(box.left for box in extents), max(box.right for box in extents)
    bottom, top = min(box.bottom for box in extents), max(box.top for box in extents)
    half = max((right - left) / 2, (top - bottom) / 2)
    middle = ((right + left) / 2, (top + bottom) / 2)
    distance = FRAMING * half
    return (middle[0], middle[1] - 1e-3 * distance, distance), (middle[0], middle[1], 0.0)


def camera_fit(reach: float) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """(position, look_at) of a camera straight above the workspace of radius `reach`, all of it in view.

    +x to the right and +y up (a hair off the pole so "up" is defined), the workspace centred: the
    panel has a column of its own (panel.py).
    """
    return camera_over([Extent.disc(reach)])


def over_the_point(point, height: float, camera) -> np.ndarray:
    """(3,) where a marker `height` above the plane draws exactly over `point` (2,) on it, seen from `camera` (3,).

    On the ray from the camera to the point: straight above it, the perspective camera would draw the
    lifted target cross 15 to 25 px off where the tips meet (a measured miss). Exact for the initial camera
    every tab starts with; orbiting the view shifts it by at most height / distance of the radius.
    """
    ground = np.array([float(point[0]), float(point[1]), 0.0])
    camera = np.asarray(camera, dtype=np.float64)
    return ground + (camera - ground) * (height / camera[2])


def camera_fit_3d(center: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """(position, look_at) of a camera in front of, beside and above the reach ball, seen along (-1, 1, -0.6).

    At 1.77 reach radii from the centre the whole ball fits viser's 75° field of view (it needs 1 / sin 37.5° =
    1.64), and the camera looks a quarter of the reach above the base, where an arm mostly works: at 1.54
    radii, looking at the base, an arm stretched straight up (a Kinova's first target) left the picture.
    """
    look_at = center + np.array([0.0, 0.0, LOOK_ABOVE_BASE * reach])
    return look_at + REACH_DISTANCE * reach * np.array([1.0, -1.0, 0.6]), look_at


REACH_DISTANCE = 1.15  # times (1, -1, 0.6): 1.77 reach radii from the point looked at
LOOK_ABOVE_BASE = 0.25  # in reach radii


def field_of_view(aspect: float) -> float:
    """The vertical field of view (radians) for a canvas `aspect` (width / height) wide: viser's own where the canvas
    is at least as wide as tall, wider where it is taller, so that it sees across as much as a square canvas does.

    The cameras are framed for viser's vertical field of view (the same camera for every tab, so the lifted target
    cross is aimed once); with a fixed vertical angle a tall window saw across less than that, and cut the
    planar reach circle at both sides.
    """
    if not np.isfinite(aspect) or aspect <= 0:
        raise ValueError(f"aspect: expected a canvas width / height > 0, got {aspect!r}")
    return float(2.0 * np.arctan(np.tan(VERTICAL_FOV / 2) / min(1.0, aspect)))


def fit_fields_of_view(server) -> None:
    """Widen the field of view of each tab whose canvas is taller than wide (and narrow it back when it is not)."""
    for client in server.get_clients().values():
        try:
            width, height = client.camera.image_width, client.camera.image_height
        except AssertionError:  # viser's way of saying the page has not sent its camera yet
            continue
        if width > 0 and height > 0:
            client.camera.fov = field_of_view(width / height)  # viser sends it only when it changes


def move_cameras(server, camera) -> None:
    """Point the camera of every open tab, and of tabs opened later, as `camera` (position, look_at) says."""
    position, look_at = camera
    server.initial_camera.position, server.initial_camera.look_at = position, look_at
    for client in server.get_clients().values():
        with client.atomic():
            client.camera.position, client.camera.look_at = position, look_at
