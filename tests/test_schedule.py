import math

import pytest
import torch

from ikdp.schedule import DiffusionSchedule, ScheduleConfig


def test_linear_betas_scaled_to_T():
    schedule = DiffusionSchedule(ScheduleConfig(timesteps=80))
    # DDPM's 1e-4 .. 0.02 at T=1000, scaled by 1000/80
    assert schedule.betas[0].item() == pytest.approx(0.00125)
    assert schedule.betas[-1].item() == pytest.approx(0.25)
    beta_1 = 0.00125 + (0.25 - 0.00125) / 79
    assert schedule.alphas_cumprod[1].item() == pytest.approx((1 - 0.00125) * (1 - beta_1), rel=1e-6)
    # posterior variance at t=1: beta_1 (1 - abar_0) / (1 - abar_1)
    expected = beta_1 * 0.00125 / (1 - (1 - 0.00125) * (1 - beta_1))
    assert schedule.posterior_variance[1].item() == pytest.approx(expected, rel=1e-5)
    assert schedule.posterior_variance[0].item() == 0.0


@pytest.mark.parametrize("timesteps", [40, 80, 100])
def test_paper_timesteps_reach_noise(timesteps):
    for kind in ("linear", "cosine"):
        schedule = DiffusionSchedule(ScheduleConfig(timesteps=timesteps, kind=kind))
        assert schedule.num_timesteps == timesteps
        assert (schedule.alphas_cumprod.diff() < 0).all()
        assert schedule.alphas_cumprod[-1] < 1e-3  # x_T is (nearly) pure noise


def test_cosine_matches_its_formula():
    schedule = DiffusionSchedule(ScheduleConfig(timesteps=100, kind="cosine"))
    f = lambda t: math.cos((t / 100 + 0.008) / 1.008 * math.pi / 2) ** 2
    assert schedule.alphas_cumprod[49].item() == pytest.approx(f(50) / f(0), rel=1e-5)


def test_karras_noise_levels_follow_edm_spacing():
    schedule = DiffusionSchedule(ScheduleConfig(timesteps=100, kind="karras", sigma_min=0.002, sigma_max=80.0))
    sigmas = (schedule.sqrt_one_minus_alphas_cumprod / schedule.sqrt_alphas_cumprod).double()
    assert sigmas[0].item() == pytest.approx(0.002, rel=1e-4)
    assert sigmas[-1].item() == pytest.approx(80.0, rel=1e-4)
    ramp = sigmas ** (1 / 7)  # rho = 7: the 7th roots are evenly spaced
    assert (ramp.diff() - ramp.diff().mean()).abs().max() < 1e-5
    assert (schedule.alphas_cumprod.diff() < 0).all() and schedule.alphas_cumprod[-1] < 1e-3
    assert (sigmas < 0.1).sum() >= 20  # the point of it: many steps at low noise
    with pytest.raises(ValueError, match="sigma_min < sigma_max"):
        DiffusionSchedule(ScheduleConfig(kind="karras", sigma_min=1.0, sigma_max=0.5))


def test_add_noise_is_the_forward_marginal():
    schedule = DiffusionSchedule()
    clean, noise = torch.ones(3, 2), torch.full((3, 2), 2.0)
    t = torch.tensor([0, 10, 79])
    noisy = schedule.add_noise(clean, noise, t)
    expected = schedule.alphas_cumprod[t].sqrt()[:, None] + 2 * (1 - schedule.alphas_cumprod[t]).sqrt()[:, None]
    torch.testing.assert_close(noisy, expected.expand(3, 2))


def test_uniform_timestep_grid():
    schedule = DiffusionSchedule()
    assert schedule.timestep_grid(None) == list(range(79, -1, -1))
    strided = schedule.timestep_grid(20)
    assert len(strided) == 20 and strided[0] == 79 and strided[-1] == 0
    assert all(a > b for a, b in zip(strided, strided[1:], strict=False))
    assert schedule.timestep_grid(4) == [79, 53, 26, 0]


def test_quadratic_timestep_grid_is_packed_near_zero():
    # t_i = (T-1)(1 - i/(n-1))^2 rounded: T = 100, n = 4 gives 99, 44, 11, 0 (99 * 4/9 = 44, 99/9 = 11)
    schedule = DiffusionSchedule(ScheduleConfig(timesteps=100))
    assert schedule.timestep_grid(4, "quadratic") == [99, 44, 11, 0]
    assert schedule.timestep_grid(8, "quadratic") == [99, 73, 51, 32, 18, 8, 2, 0]
    assert schedule.timestep_grid(2, "quadratic") == [99, 0] and schedule.timestep_grid(1, "quadratic") == [99]
    # at n = 16 rounding gives 0.44 -> 0 for the last but one: raised to 1, one above the last
    assert schedule.timestep_grid(16, "quadratic")[-4:] == [4, 2, 1, 0]
    # every n up to T: strictly decreasing from T-1 to 0, all T at n = T
    for steps in range(2, 101):
        grid = schedule.timestep_grid(steps, "quadratic")
        assert len(grid) == steps and grid[0] == 99 and grid[-1] == 0
        assert all(a > b for a, b in zip(grid, grid[1:], strict=False))
    assert schedule.timestep_grid(100, "quadratic") == list(range(99, -1, -1))


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda s: s.timestep_grid(81), "steps"),
        (lambda s: s.timestep_grid(0), "steps"),
        (lambda s: s.timestep_grid(4, "cubic"), r"spacing: expected one of \('uniform', 'quadratic'\), got 'cubic'"),
        (lambda s: s.add_noise(torch.zeros(1, 2), torch.zeros(1, 2), torch.tensor([-1])), "timestep"),
        (lambda s: s.predict_clean(torch.zeros(1, 2), 3, torch.zeros(1, 2), "v"), "prediction"),
    ],
)
def test_bad_arguments_raise(call, message):
    with pytest.raises(ValueError, match=message):
        call(DiffusionSchedule())


def test_bad_config_raises():
    with pytest.raises(ValueError, match="schedule kind"):
        DiffusionSchedule(ScheduleConfig(kind="quadratic"))
    with pytest.raises(ValueError, match="timesteps"):
        DiffusionSchedule(ScheduleConfig(timesteps=0))
