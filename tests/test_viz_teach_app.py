"""The teaching parts in a running viewer (no browser): the tour's views, noise it, again from the same x_T."""

from __future__ import annotations

import numpy as np
import pytest
from viz_helpers import running_app, settle, shipped_solver_or_skip

from ikdp_viz.teaching import is_forward
from ikdp_viz.tour import TOUR


@pytest.fixture(scope="module")
def n4():
    return shipped_solver_or_skip("ikdp_n4")


def wait_for_step(app) -> None:
    assert app.tour.applied.wait(90), "the tour's view was not applied"
    settle(app)


def test_the_tour_puts_each_view_on_screen_and_leaving_returns_home(n4):
    with running_app(n4, tour=True) as app:
        wait_for_step(app)
        panel = app.panel
        assert panel.teach.tour.text.content.startswith("**1 of 6 · Noise becomes a pose**")
        assert not panel.show_trail.value and panel.teach.tour.take.visible is False
        assert app.solved.view.labels[app.state] == 0  # played to the final poses
        app.tour.show(1)  # x̂0 at t = 50
        wait_for_step(app)
        assert panel.show_estimate.value and int(app.solved.view.labels[app.state]) == TOUR[1].view.timestep
        app.tour.show(3)  # many answers
        wait_for_step(app)
        assert app.solved.view.num_samples == 64
        app.tour.show(4)  # the 2-link arm's two branches
        wait_for_step(app)
        assert app.solver.num_links == 2 and panel.joint_space.show.value
        np.testing.assert_allclose(app.target, TOUR[4].view.target)
        app.tour.show(5)  # DDPM against DDIM: back on the model the tour began on
        wait_for_step(app)
        assert app.solver.num_links == 4 and app.solved.compare is not None
        app.tour.leave()
        wait_for_step(app)
        assert panel.teach.tour.take.visible and not panel.teach.tour.next.visible
        assert panel.show_trail.value and str(panel.learn.compare.value) == "off" and app.solved.view.num_samples == 16


@pytest.mark.parametrize(("sampler", "lands_elsewhere"), [("ddpm", True), ("ddim", False)])
def test_again_from_the_same_x_T(n4, sampler, lands_elsewhere):
    with running_app(n4) as app:
        app.panel.play_on_move.value = False
        app.panel.sampler.value = sampler
        settle(app)
        first, noise = app.solved.view.final_joints.copy(), app.solved.view.joints[0].copy()
        app.again()
        settle(app)
        assert app.solved.request.rerun == 1
        moved = float(np.linalg.norm(app.solved.view.final_joints - first, axis=-1).max())
        text = app.panel.teach.again_text.content
        assert text.startswith("**Again from the same x_T**, run 2")
        assert ("landed elsewhere" in text) is lands_elsewhere and (moved > 1e-3) is lands_elsewhere
        np.testing.assert_allclose(app.solved.view.joints[0], noise)  # the pure noise x_T drawn is the same
        if lands_elsewhere:
            assert f"moved {moved:.2f}" in text


def test_noise_it_draws_the_final_poses_going_to_noise(n4):
    with running_app(n4) as app:
        app.panel.play_on_move.value = False
        settle(app)
        finals = app.solved.view.final_joints.copy()
        forward = app.noise_it(play=False)
        assert is_forward(app.solved) and app.solved is forward
        np.testing.assert_allclose(app.solved.view.joints[-1], finals, atol=1e-5)  # t = 0: the poses it noised
        app.show_state(0)  # t = T
        assert "forward process (noise it)" in app.panel.readout_text.content
        assert np.median(app.solved.view.tip_error[0]) > 10 * np.median(app.solved.view.tip_error[-1])
        assert app.noise_it() is None  # a forward process is not noised again


def test_a_t_the_student_never_visits_is_said_when_the_slider_snaps(n4):
    with running_app(n4) as app:
        app.panel.play_on_move.value = False
        app.panel.sampler.value = "student"
        settle(app)
        labels = [int(label) for label in app.solved.view.labels]
        asked = next(t for t in range(1, 80) if t not in labels)
        app.panel.timestep.value = asked
        text = app.panel.readout_text.content
        assert f"t = {asked} is no step of this sampler (it visits t = {', '.join(map(str, labels))})" in text
        assert int(app.panel.timestep.value) in labels
        app.show_state(0)  # a step by its index: nothing was asked that it lacks
        assert "is no step of this sampler" not in app.panel.readout_text.content
