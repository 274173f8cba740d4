"""The page-latency benchmark's geometry: the gizmo is pressed where a viser camera draws it (no browser here)."""

import math

import numpy as np
import pytest

from benchmarks.viz_page_latency import GRIP_ALONG_ARROW, MASK_SCALE, grip, project, rotation_matrix, summary

BOX = (10.0, 20.0, 800.0, 600.0)  # the canvas: x, y, width, height in page pixels
FOV = math.radians(60)
FOCAL = 300 / math.tan(FOV / 2)  # half the canvas height over tan(fov / 2)


def top_down(height: float) -> dict:
    """A camera `height` over the origin looking down, world +y up the screen (OpenCV frame: x right, y down)."""
    return {"position": [0.0, 0.0, height], "wxyz": [0.0, 1.0, 0.0, 0.0], "fov": FOV, "aspect": 800 / 600}


def test_a_quarter_turn_about_z_takes_x_to_y():
    turn = rotation_matrix([math.cos(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4)])
    np.testing.assert_allclose(turn @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(rotation_matrix([2.0, 0.0, 0.0, 0.0]), np.eye(3))  # normalised first


def test_a_top_down_camera_draws_x_right_and_y_up_the_page():
    centre = np.array([BOX[0] + 400, BOX[1] + 300])
    pixels = project([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 5.0]], top_down(10.0), BOX)
    np.testing.assert_allclose(pixels[0], centre)
    np.testing.assert_allclose(pixels[1], centre + [FOCAL / 10, 0.0])
    np.testing.assert_allclose(pixels[2], centre - [0.0, FOCAL / 10])
    np.testing.assert_allclose(pixels[3], centre + [FOCAL / 5, 0.0])  # halfway up to the camera: twice as far out


def test_a_camera_looking_along_x_sees_depth_as_smaller():
    # looking along world +x with world +z up: camera x = -world y, camera y = -world z, camera z = world x
    look = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])  # columns: camera axes in the world
    w = math.sqrt(1 + np.trace(look)) / 2
    wxyz = [
        w,
        (look[2, 1] - look[1, 2]) / (4 * w),
        (look[0, 2] - look[2, 0]) / (4 * w),
        (look[1, 0] - look[0, 1]) / (4 * w),
    ]
    camera = {"position": [0.0, 0.0, 0.0], "wxyz": wxyz, "fov": FOV, "aspect": 800 / 600}
    near, far = project([[2.0, -1.0, 1.0], [4.0, -1.0, 1.0]], camera, BOX)
    centre = np.array([BOX[0] + 400, BOX[1] + 300])
    np.testing.assert_allclose(near, centre + [FOCAL / 2, -FOCAL / 2])  # world -y is right, +z is up
    np.testing.assert_allclose(far, centre + [FOCAL / 4, -FOCAL / 4])


def test_the_grip_is_on_the_longest_looking_arrow_and_the_disc_covers_the_gizmo():
    gizmo = {"position": [2.0, 1.0, 0.0], "wxyz": [1.0, 0.0, 0.0, 0.0], "scale": 0.5}
    centre = project([2.0, 1.0, 0.0], top_down(10.0), BOX)
    arrow = 0.5 * FOCAL / 10  # an arrow's length on the page
    pressed, direction, radius = grip(gizmo, top_down(10.0), BOX, axes=2)  # x and y look alike: x, the first
    np.testing.assert_allclose(direction, [1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(pressed, centre + [GRIP_ALONG_ARROW * arrow, 0.0])
    assert radius == pytest.approx(MASK_SCALE * arrow)

    turned = {**gizmo, "wxyz": [math.cos(0.3), 0.0, math.sin(0.3), 0.0]}  # x tipped toward the camera: y looks longer
    pressed, direction, _ = grip(turned, top_down(10.0), BOX, axes=3)
    np.testing.assert_allclose(direction, [0.0, -1.0], atol=1e-12)
    np.testing.assert_allclose(pressed, centre - [0.0, GRIP_ALONG_ARROW * arrow])


def test_the_summary_names_the_median_and_the_tenth_and_ninetieth_percentiles():
    assert summary(list(range(11))) == {"median": 5.0, "p10": 1.0, "p90": 9.0, "n": 11}
    assert summary([]) == {"n": 0}
