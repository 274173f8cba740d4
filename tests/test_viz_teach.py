"""The viewer's teaching pieces as plain data: the tour's steps, the glossary, the schedule plot's data."""

import numpy as np
import pytest

from ikdp.schedule import DiffusionSchedule, ScheduleConfig
from ikdp_viz.planar_scene import state_labels
from ikdp_viz.readouts import (
    GLOSSARY,
    branch_name,
    define,
    glossary_markdown,
    held_text,
    joint_space_title,
    model_words,
)
from ikdp_viz.solving import rerun_seed
from ikdp_viz.teaching import (
    FORWARD,
    Rerun,
    forward_solved,
    is_forward,
    largest_move,
    schedule_curves,
    schedule_plot_data,
    visited_count,
)
from ikdp_viz.tour import TOUR, TWO_LINK_MODEL, tour_markdown


def test_tour_is_six_one_sentence_steps_the_issue_lists():
    assert len(TOUR) == 6
    for step in TOUR:
        assert step.sentence.count(". ") == 0, f"{step.title!r} says more than one sentence"
    views = [step.view for step in TOUR]
    assert not views[0].show_trail  # noise becomes a pose, trail off
    assert views[1].show_estimate and views[1].timestep > 0  # x̂0 at a noisy step
    assert views[3].samples == 64  # many answers
    assert views[4].model == TWO_LINK_MODEL and views[4].joint_space  # two branches, named
    assert "elbow up" in TOUR[4].sentence and "elbow down" in TOUR[4].sentence
    assert views[5].compare == "ddim" and views[5].sampler == "ddpm"  # stochastic against deterministic
    assert tour_markdown(0).startswith("**1 of 6 · Noise becomes a pose**")
    with pytest.raises(ValueError, match="index: expected a tour step 0 .. 5, got 6"):
        tour_markdown(6)


def test_glossary_defines_the_words_the_page_uses():
    for term in ("x̂0", "ᾱ_t", "σ", "x_t", "ODE", "DPM-Solver++", "DLS", "FiLM",
                 "cossin", "heading", "student", "teacher", "p95", "prior"):  # fmt: skip
        assert term in GLOSSARY
    assert define("prior").startswith("prior: the poses the model was trained on, before any target")
    assert glossary_markdown().count("\n") == len(GLOSSARY) - 1
    with pytest.raises(ValueError, match="term: expected one of the glossary's"):
        define("entropy")


def test_schedule_curves_on_the_slider_axis():
    schedule = DiffusionSchedule(ScheduleConfig(timesteps=80))
    curves = schedule_curves(schedule.alphas_cumprod)
    assert curves.t[0] == 0 and curves.t[-1] == 80
    assert curves.sigma[0] == 0 and curves.alpha_bar[0] == 1  # t = 0: the clean pose
    assert curves.sigma[80] == pytest.approx(float(schedule.sqrt_one_minus_alphas_cumprod[79]), rel=1e-6)
    assert np.all(np.diff(curves.sigma) > 0)
    with pytest.raises(ValueError, match="alphas_cumprod: expected a"):
        schedule_curves(np.array([0.5, 0.0]))


def test_schedule_plot_marks_the_sampler_steps_and_the_step_shown():
    schedule = DiffusionSchedule(ScheduleConfig(timesteps=80))
    curves = schedule_curves(schedule.alphas_cumprod)
    ddim = state_labels(schedule.timestep_grid(20))  # 21 states: 20 steps and the final pose
    data = schedule_plot_data(curves, 33.0, ddim)
    assert visited_count(data) == 21
    assert visited_count(schedule_plot_data(curves, 33.0, state_labels(schedule.timestep_grid(None)))) == 81
    assert np.flatnonzero(np.isfinite(data[4])).tolist() == [33]
    assert data[4][33] == curves.sigma[33]
    with pytest.raises(ValueError, match=r"now: expected a diffusion time in \[0, 80\] or None, got 81"):
        schedule_plot_data(curves, 81, ddim)


def test_model_box_speaks_a_users_language():
    metadata = {
        "model": {"denoiser": {"kind": "film"}, "representation": "cossin", "schedule": {"kind": "linear"}},
        "metrics": {"tip_error_median": 0.0072, "tip_error_p95": 0.0157, "step": 30000, "sampler": "ddpm raw, K=1",
                    "eval_targets": 500},
    }  # fmt: skip
    text = model_words(4, (1.0, 1.0, 1.0, 1.0), 80, metadata, student_steps=2)
    assert "**A 4-link planar arm** (N = 4), bones 1, 1, 1, 1 long; it reaches up to 4 from its base." in text
    assert "T = 80 steps from pure noise to a pose" in text
    assert "on 500 random targets, half the tips land within 0.0072 bone lengths" in text
    assert "(p95; DDPM, one sample per target, no polish)" in text and "ddpm raw" not in text
    assert "land in 2 steps" in text
    assert "student" not in model_words(2, (1.0, 0.5), 20, {}) and "How well" not in model_words(2, (1.0, 0.5), 20, {})


def test_rerun_seeds_and_the_moved_words():
    assert rerun_seed(0, 1) != rerun_seed(0, 2) and rerun_seed(0, 1) != 1  # never the comparison's seed + 1
    with pytest.raises(ValueError, match="run: expected a rerun numbered from 1, got 0"):
        rerun_seed(5, 0)
    before = np.zeros((2, 3, 2))
    after = before.copy()
    after[1, 2] = (0.3, 0.4)
    assert largest_move(before, after) == pytest.approx(0.5)
    assert largest_move(before, before) == 0.0
    with pytest.raises(ValueError, match=r"current: expected arms of shape \(2, 3, 2\)"):
        largest_move(before, after[:1])
    text = Rerun(2, "ddpm", 0.834, "ddim", 0.0).text()
    assert text.startswith("**Again from the same x_T**, run 3: ddpm landed elsewhere: a joint moved 0.83")
    assert "beside it, ddim landed on the same poses as the run before" in text


def test_noise_it_takes_the_poses_on_screen_to_pure_noise_on_the_same_slider():
    import ikdp
    from ikdp_viz.solving import SolveRequest, solve

    solver = ikdp.load("ikdp_n4")
    request = SolveRequest(
        solver=solver, target=np.array([2.0, 1.0]), num_samples=4, sampler="ddim", steps=10, refine_steps=0,
        seed=0, arrival=0.0, animate=False,
    )  # fmt: skip
    solved = solve(request)
    forward = forward_solved(solved, seed=3)
    assert is_forward(forward) and not is_forward(solved)
    view = forward.view
    assert view.num_states == 81 and view.labels[0] == 80 and view.labels[-1] == 0  # the slider's t = T .. 0
    np.testing.assert_allclose(view.joints[-1], solved.view.final_joints, atol=1e-5)  # t = 0: the poses on screen
    assert np.median(view.tip_error[0]) > 0.5 > np.median(view.tip_error[-1])  # pure noise misses the target
    assert forward.request.sampler == FORWARD


def test_joint_space_words_name_the_branches_and_the_held_joints():
    from ikdp_viz.joint_space import two_link_solutions

    solutions = two_link_solutions((1.0, 1.0), (1.2, 0.8)).points  # (2, 2) the two exact poses
    names = sorted(branch_name((1.0, 1.0), pose) for pose in solutions)
    assert names == ["elbow down", "elbow up"]
    up = next(pose for pose in solutions if branch_name((1.0, 1.0), pose) == "elbow up")
    assert np.sin(up[0]) * 1.0 > 0.8 * 1.0 / 2  # its elbow sits above the line from the base to (1.2, 0.8)
    text = held_text(("θ1", "θ2", "θ3", "θ4"), (0, 1), np.radians([10.0, 20.0, 35.0, -120.0]))
    assert text == "arrows with θ3 = 35°, θ4 = -120° (the blue sample's, at the step shown)"
    assert held_text(("θ1", "θ2"), (0, 1), [0.0, 1.0]) == ""
    with pytest.raises(ValueError, match="headings: expected 4 angles, one per joint, got 2"):
        held_text(("θ1", "θ2", "θ3", "θ4"), (0, 1), [0.0, 1.0])
    assert "θ1 (→) and θ2 (↑)" in joint_space_title("θ1", "θ2")


def test_the_followed_trail_is_fainter_than_the_final_samples_until_the_pose_forms():
    from ikdp_viz.planar_scene import emphasis_colors
    from ikdp_viz.style import ACCENT_DARK, OTHERS_FINAL, TRAIL_FAINT

    arms, trail = emphasis_colors(81, 16, 3, "highlighted")
    followed = trail[:, 3].astype(int)  # (S+1, 3) the followed sample's trail, t = T first
    assert tuple(followed[0]) == TRAIL_FAINT and tuple(followed[-1]) == ACCENT_DARK
    lighter = followed.sum(axis=1) > sum(OTHERS_FINAL)
    assert lighter[:55].all()  # t = 80 .. 26, where the poses are mostly noise: lighter than the grey finals
    assert tuple(arms[-1, 0]) == OTHERS_FINAL and tuple(arms[-1, 3]) == ACCENT_DARK
