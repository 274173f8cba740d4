"""The viewer's teaching pieces as plain data: the tour's steps, the glossary, the schedule plot's data."""

import numpy as np
import pytest

from ikdp.schedule import DiffusionSchedule, ScheduleConfig
from ikdp_viz.glossary import GLOSSARY, define, glossary_markdown
from ikdp_viz.model_words import model_words
from ikdp_viz.scene import state_labels
from ikdp_viz.schedule_plot import schedule_curves, schedule_plot_data, visited_count
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
    with pytest.raises(ValueError, match=r"now: expected a diffusion time in \[0, 80\], got 81"):
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
