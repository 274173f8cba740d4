"""The animation's clock spaced by noise level (ikdp_viz/frame.py) and the writer's Animation that follows it."""

from __future__ import annotations

import numpy as np
import pytest

from ikdp.schedule import DiffusionSchedule, ScheduleConfig
from ikdp_viz.frame import clock_note, noise_levels, state_offsets
from ikdp_viz.intent import Animation
from ikdp_viz.planar_scene import state_labels


@pytest.fixture
def linear_schedule_sigmas():
    """The shipped planar models' schedule: linear betas, T = 80; sigma of DDPM's 81 states."""
    schedule = DiffusionSchedule(ScheduleConfig(timesteps=80, kind="linear"))
    labels = state_labels(list(range(79, -1, -1)))  # DDPM: t = 80 .. 0
    return labels, noise_levels(labels, schedule.sqrt_one_minus_alphas_cumprod.numpy())


def test_noise_levels_read_the_schedule_at_each_states_time(linear_schedule_sigmas):
    labels, sigmas = linear_schedule_sigmas
    betas = (1000 / 80) * np.linspace(1e-4, 0.02, 80)  # the linear schedule by hand (ikdp.schedule.make_betas)
    alphabar = np.cumprod(1 - betas)
    assert sigmas[0] == pytest.approx(np.sqrt(1 - alphabar[79]), rel=1e-5)  # t = T
    assert sigmas[40] == pytest.approx(np.sqrt(1 - alphabar[39]), rel=1e-5)  # t = 40 reads entry 39
    assert sigmas[-2] == pytest.approx(np.sqrt(betas[0]), rel=1e-4)  # t = 1: sqrt(beta_1)
    assert sigmas[-1] == 0.0 and (np.diff(sigmas) <= 0).all()
    with pytest.raises(ValueError, match="labels"):
        noise_levels(np.array([81, 0]), np.ones(80))


def test_by_noise_level_the_noisy_steps_pass_quickly_and_the_last_ones_fill_the_time(linear_schedule_sigmas):
    labels, sigmas = linear_schedule_sigmas
    by_noise, by_step = state_offsets(sigmas, "noise level", 4.0), state_offsets(sigmas, "step", 4.0)
    for offsets in (by_noise, by_step):
        assert offsets[0] == 0.0 and offsets[-1] == pytest.approx(4.0) and (np.diff(offsets) >= 0).all()
    assert np.allclose(np.diff(by_step), 4.0 / 80)
    noisy = labels >= 33  # sigma > 0.9: the first 48 steps
    assert sigmas[noisy].min() > 0.9 > sigmas[~noisy].max()
    assert by_step[48] == pytest.approx(2.4) and by_noise[48] < 0.5  # 2.4 s of noise by step, under 0.5 s by sigma
    assert 4.0 - by_noise[labels == 20][0] > 2.5  # and the last 20 steps take most of the 4 s
    note = clock_note(labels, by_noise, sigmas)
    assert "t = 80 .. 33 (σ > 0.9) take 0.4 s" in note and "t = 20 .. 0 take 2.7 s" in note
    with pytest.raises(ValueError, match="clock"):
        state_offsets(sigmas, "log", 4.0)


def test_an_animation_with_offsets_shows_each_state_from_its_offset():
    offsets = np.array([0.0, 0.1, 0.2, 2.0, 4.0])
    animation = Animation(first=0, last=4, seconds_per_state=1.0, started_at=10.0, offsets=offsets)
    assert [animation.state_at(10.0 + s) for s in (0.0, 0.15, 0.5, 1.99, 2.0, 3.9, 9.0)] == [0, 1, 2, 2, 3, 3, 4]
    resumed = Animation(first=2, last=4, seconds_per_state=1.0, started_at=0.0, offsets=offsets)  # from state 2
    assert [resumed.state_at(now) for now in (0.0, 1.79, 1.8, 3.8)] == [2, 2, 3, 4]
