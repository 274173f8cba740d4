"""Same noise, two samplers: DDPM and DDIM from one x_T, side by side, and their tip errors in one chart."""

from __future__ import annotations

import numpy as np
import pytest
from viz_helpers import running_app, settle

import ikdp
from ikdp_viz.compare_view import offset
from ikdp_viz.planar_scene import compare_curve, line_colors


@pytest.fixture
def app(tiny_checkpoint):
    with running_app(ikdp.load(tiny_checkpoint), animation_seconds=0.0, target=(1.0, 0.7)) as app:
        settle(app)
        yield app


def test_the_second_sampler_starts_from_the_same_noise_and_leaves_the_first_unchanged(app):
    alone = app.solved.view
    app.panel.steps.value = 4
    app.panel.learn.compare.value = "ddim"
    settle(app)
    solved = app.solved
    view, compare = solved.view, solved.compare
    assert solved.request.compare_sampler == "ddim" and compare.num_states == 5  # DDIM with the panel's 4 steps
    assert np.array_equal(view.joints, alone.joints)  # the DDPM solve is the one shown without the comparison
    assert np.allclose(compare.joints[0], view.joints[0])  # x_T: the very same noise
    assert not np.allclose(compare.joints[-1], view.joints[-1])  # then each sampler its own way
    # drawn to the left, at the state nearest the main one's diffusion time
    nodes = app.writer.stage.compare.nodes
    reach = app.solver.reach[1]
    app.panel.timestep.value = 6
    shown = int(np.argmin(np.abs(compare.labels - 6)))
    drawn = nodes["links"].points.reshape(compare.num_samples, compare.num_links, 2, 3)[:, :, 0, :2]
    assert np.allclose(drawn, compare.joints[shown][:, :-1] + (offset(reach), 0.0), atol=1e-5)
    assert "DDIM (deterministic ODE), 4 steps" in nodes["title"].text and "same x_T" in nodes["main_title"].text
    # one chart: a fifth column, the followed sample's DDIM tip error on the same t axis
    data, series = app.panel.plot.data, app.panel.plot.series
    assert len(data) == len(series) == 5 and series[-1]["label"] == "ddim"
    assert np.allclose(data[-1], compare_curve(view, compare, app.highlight_index()))
    t0 = int(np.flatnonzero(data[0] == 0)[0])
    assert data[-1][t0] == pytest.approx(np.log10(max(compare.tip_error[-1, app.highlight_index()], 1e-6)))
    # off again: the view, the extra series and the wide camera go
    app.panel.learn.compare.value = "off"
    settle(app)
    assert app.solved.compare is None and not app.writer.stage.compare.shown
    assert len(app.panel.plot.series) == len(app.panel.plot.data) == 4
    assert app.server.initial_camera.position[0] == pytest.approx(0.0)


def test_comparing_a_sampler_with_itself_is_no_comparison(app):
    app.panel.sampler.value = "ddim"
    app.panel.learn.compare.value = "ddim"
    settle(app)
    assert app.solved.compare is None and not app.writer.stage.compare.shown


def test_the_compared_arms_take_their_colours_from_the_frame(app):
    """The drawing loop's frame holds the comparison's colours (its palette), as it holds the main arms': the view
    draws those, so a frame drawn with other colours shows them."""
    import dataclasses

    app.panel.learn.compare.value = "ddim"
    settle(app)
    palette = app.writer.frame.palette
    compare = app.solved.compare
    assert palette.compare_arms.shape == (compare.num_states, compare.num_samples, 3)
    assert palette.compare_trail.shape[:2] == (compare.num_states, compare.num_samples * compare.num_links)
    marked = dataclasses.replace(palette, compare_arms=np.full_like(palette.compare_arms, 7))
    frame = dataclasses.replace(app.writer.frame, palette=marked)
    app.writer.run(lambda writer: writer.draw_scene(frame))
    links = app.writer.stage.compare.nodes["links"].colors
    assert np.all(links == line_colors(np.full(3, 7, np.uint8))), np.unique(links)  # as lines take colours
