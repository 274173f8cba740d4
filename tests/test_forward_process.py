import math

import pytest
import torch

import ikdp
from ikdp.forward_process import forward_trajectory
from ikdp.representation import AngleRepresentation
from ikdp.schedule import DiffusionSchedule, ScheduleConfig


def test_forward_trajectory_starts_clean_and_mixes_as_the_schedule_says():
    schedule = DiffusionSchedule(ScheduleConfig(timesteps=80))
    representation = AngleRepresentation("angle", 3)
    clean = torch.tensor([[0.3, -1.2, 2.0], [0.0, 0.5, -0.5]])  # (K=2, J=3)
    noise = torch.tensor([[0.1, -0.2, 0.05], [0.3, 0.0, -0.1]])  # (K, D=3)
    states = forward_trajectory(schedule, representation, clean, noise)
    assert states.shape == (81, 2, 3)
    assert torch.allclose(states[0], clean, atol=1e-6)  # t = 0: the pose itself
    # t = 40 is the schedule's index 39: sqrt(abar) x0 + sqrt(1 - abar) eps, in theta / pi, decoded
    abar = schedule.alphas_cumprod[39].double()
    expected = (abar.sqrt() * clean[0, 0].double() / math.pi + (1 - abar).sqrt() * 0.1) * math.pi
    assert states[40, 0, 0].item() == pytest.approx(expected.item(), abs=1e-5)
    # the same eps at every t: the noisiest state is almost the noise alone
    assert torch.allclose(states[80], representation.decode(noise), atol=0.1)


def test_forward_trajectory_matches_add_noise_in_cossin():
    schedule = DiffusionSchedule(ScheduleConfig(timesteps=20, kind="cosine"))
    representation = AngleRepresentation("cossin", 2)
    clean = torch.tensor([[0.4, 2.5]])
    noise = torch.randn((1, 4), generator=torch.Generator().manual_seed(0))
    states = forward_trajectory(schedule, representation, clean, noise)
    noisy = schedule.add_noise(representation.encode(clean), noise, torch.tensor([11]))
    assert torch.allclose(states[12], representation.decode(noisy), atol=1e-6)


def test_forward_trajectory_rejects_wrong_shapes():
    schedule = DiffusionSchedule(ScheduleConfig(timesteps=10))
    representation = AngleRepresentation("cossin", 2)
    with pytest.raises(ValueError, match=r"clean: expected joint values of shape \(K, 2\), got \(3,\)"):
        forward_trajectory(schedule, representation, torch.zeros(3), torch.zeros(1, 4))
    with pytest.raises(ValueError, match=r"noise: expected eps of shape \(1, 4\), got \(1, 2\)"):
        forward_trajectory(schedule, representation, torch.zeros(1, 2), torch.zeros(1, 2))


@pytest.mark.parametrize(
    ("model", "sampler", "steps", "repeats"),
    [("ikdp_n2", "ddpm", None, False), ("ikdp_n2", "ddim", 20, True), ("ikdp_n4", "student", None, True)],
)
def test_same_x_T_new_sampling_noise(model, sampler, steps, repeats):
    """From one x_T, a new generator changes DDPM's landing (fresh noise every step), not DDIM's or the student's."""
    solver = ikdp.load(model)
    x_T = torch.randn((1, 4, solver.noise_dim), generator=torch.Generator().manual_seed(3))
    target = torch.tensor([[1.2, 0.8]]) if model == "ikdp_n2" else torch.tensor([[2.0, 1.0]])
    runs = [
        solver.solve(
            target, num_samples=4, sampler=sampler, steps=steps, initial_noise=x_T,
            generator=torch.Generator().manual_seed(seed),
        ).angles
        for seed in (1, 2)
    ]  # fmt: skip
    same = torch.allclose(runs[0], runs[1])
    assert same is repeats
