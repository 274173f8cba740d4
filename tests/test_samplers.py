"""The sampler registry: each update by hand, step for step against diffusers, and the one loop."""

import warnings

import pytest
import torch

import ikdp
from ikdp.samplers import (
    SAMPLERS,
    AncestralSampler,
    DDIMSampler,
    DDPMSampler,
    DPMSolverPP2MSampler,
    make_sampler,
    sampler_names,
)
from ikdp.sampling import step_conditions
from ikdp.schedule import DiffusionSchedule, ScheduleConfig, make_betas

with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    diffusers = pytest.importorskip("diffusers")


def step(sampler, index, sample, clean, generator=None):
    return sampler.step(index, sample, clean, out=torch.empty_like(sample), generator=generator)


def test_registry_names_and_bad_names():
    assert sampler_names() == ("ddpm", "ddim", "dpmpp2m", "ancestral")
    assert not SAMPLERS["ddpm"].supports_steps and SAMPLERS["ddim"].supports_steps
    schedule = DiffusionSchedule()
    with pytest.raises(
        ValueError, match=r"sampler: expected one of \('ddpm', 'ddim', 'dpmpp2m', 'ancestral'\), got 'heun'"
    ):
        make_sampler("heun", schedule)
    with pytest.raises(ValueError, match="steps: DDPM runs all 80 steps"):
        make_sampler("ddpm", schedule, 10)
    with pytest.raises(ValueError, match="steps"):
        make_sampler("ddim", schedule, 81)
    with pytest.raises(ValueError, match="decreasing"):
        DDIMSampler(schedule, timesteps=[10, 20])
    with pytest.raises(ValueError, match=r"spacing: expected one of \('uniform', 'quadratic'\), got 'even'"):
        make_sampler("ddim", schedule, 4, spacing="even")


@pytest.mark.parametrize("name", ["ddim", "dpmpp2m", "ancestral"])
def test_spacing_chooses_the_grid_and_the_coefficients_follow(name):
    schedule = DiffusionSchedule(ScheduleConfig(timesteps=100, kind="cosine"))
    packed = make_sampler(name, schedule, 4, spacing="quadratic")
    assert packed.timesteps == [99, 44, 11, 0] and packed.spacing == "quadratic"
    assert make_sampler(name, schedule, 4).timesteps == [99, 66, 33, 0]
    # the same sampler on the same explicit timesteps: spacing only picks the grid
    explicit = SAMPLERS[name](schedule, timesteps=[99, 44, 11, 0])
    assert packed.coef_clean == explicit.coef_clean and packed.coef_noisy == explicit.coef_noisy
    # the DDPM runs all T steps, so every spacing is the same run
    assert make_sampler("ddpm", schedule, spacing="quadratic").timesteps == list(range(99, -1, -1))


def test_ddpm_step_by_hand():
    schedule = DiffusionSchedule()
    sampler = DDPMSampler(schedule)
    clean, sample = torch.tensor([[0.5, -0.2]]), torch.tensor([[1.0, 2.0]])
    index = sampler.timesteps.index(10)
    result = step(sampler, index, sample, clean, torch.Generator().manual_seed(3))
    z = torch.randn((1, 2), generator=torch.Generator().manual_seed(3))
    abar, abar_prev = schedule.alphas_cumprod[10].double(), schedule.alphas_cumprod[9].double()
    beta = schedule.betas[10].double()
    mean = abar_prev.sqrt() * beta / (1 - abar) * clean + (1 - beta).sqrt() * (1 - abar_prev) / (1 - abar) * sample
    expected = mean + (beta * (1 - abar_prev) / (1 - abar)).sqrt() * z
    torch.testing.assert_close(result, expected.float())
    # the last step adds no noise and lands on the clean estimate
    torch.testing.assert_close(step(sampler, len(sampler.timesteps) - 1, sample, clean), clean)


def test_ddim_step_keeps_the_implied_noise():
    schedule = DiffusionSchedule()
    sampler = DDIMSampler(schedule, timesteps=[60, 30, 5])
    clean, noise = torch.tensor([[0.3, 0.4]]), torch.tensor([[-1.0, 0.5]])
    x_t = schedule.add_noise(clean, noise, torch.tensor([60]))
    torch.testing.assert_close(step(sampler, 0, x_t, clean), schedule.add_noise(clean, noise, torch.tensor([30])))
    torch.testing.assert_close(step(sampler, 2, x_t, clean), clean)  # the last step lands on x̂0


def diffusers_kwargs(schedule):
    return {"num_train_timesteps": schedule.num_timesteps, "trained_betas": schedule.betas.numpy()}


def same_alphas(theirs, schedule):
    """diffusers keeps alpha_cumprod in float32 and computes in the samples' dtype. Give it ours in
    float64 and float64 samples: the comparison then measures our float32 update, not its rounding."""
    theirs.alphas_cumprod = torch.cumprod(1 - make_betas(schedule.config), dim=0)
    return theirs


@pytest.mark.parametrize("kind", ["linear", "cosine"])
def test_ddpm_matches_diffusers_step_for_step(kind):
    schedule = DiffusionSchedule(ScheduleConfig(kind=kind))
    theirs = diffusers.DDPMScheduler(
        **diffusers_kwargs(schedule), variance_type="fixed_small", clip_sample=False, prediction_type="sample"
    )
    same_alphas(theirs, schedule)
    theirs.set_timesteps(schedule.num_timesteps)
    ours = DDPMSampler(schedule)
    assert ours.timesteps == theirs.timesteps.tolist()
    data = torch.Generator().manual_seed(0)
    x = torch.randn((8, 6), generator=data)
    for index, t in enumerate(ours.timesteps):
        clean = torch.randn((8, 6), generator=data)
        # diffusers draws its noise in the samples' dtype (float64 here); swap it for our float32 draw
        theirs_noise = torch.randn((8, 6), generator=torch.Generator().manual_seed(index), dtype=torch.float64)
        our_noise = torch.randn((8, 6), generator=torch.Generator().manual_seed(index)).double()
        std = theirs._get_variance(t) ** 0.5 if t > 0 else 0.0
        theirs_step = theirs.step(clean.double(), t, x.double(), generator=torch.Generator().manual_seed(index))
        expected = (theirs_step.prev_sample + std * (our_noise - theirs_noise)).float()
        x = step(ours, index, x, clean, torch.Generator().manual_seed(index))
        torch.testing.assert_close(x, expected, atol=1e-6, rtol=0)


@pytest.mark.parametrize("steps", [5, 10, 20])
@pytest.mark.parametrize("eta, sampler_class", [(0.0, DDIMSampler), (1.0, AncestralSampler)])
def test_ddim_and_ancestral_match_diffusers_step_for_step(steps, eta, sampler_class):
    # the ancestral sampler is diffusers' DDIM with eta = 1 (its noise passed in), DDIM's is eta = 0
    schedule = DiffusionSchedule()
    theirs = diffusers.DDIMScheduler(
        **diffusers_kwargs(schedule),
        clip_sample=False,
        prediction_type="sample",
        set_alpha_to_one=True,
        timestep_spacing="trailing",
    )
    same_alphas(theirs, schedule)
    theirs.set_timesteps(steps)
    ours = sampler_class(schedule, timesteps=theirs.timesteps.tolist())
    data = torch.Generator().manual_seed(1)
    x = torch.randn((8, 6), generator=data)
    for index, t in enumerate(ours.timesteps):
        clean = torch.randn((8, 6), generator=data)
        noise = torch.randn((8, 6), generator=torch.Generator().manual_seed(index))
        expected = theirs.step(clean.double(), t, x.double(), eta=eta, variance_noise=noise.double()).prev_sample
        x = step(ours, index, x, clean, torch.Generator().manual_seed(index))
        torch.testing.assert_close(x, expected.float(), atol=1e-5 if eta else 1e-6, rtol=0)


def test_ancestral_on_every_step_is_the_ddpm():
    schedule = DiffusionSchedule(ScheduleConfig(timesteps=100, kind="cosine"))
    strided, every = AncestralSampler(schedule), DDPMSampler(schedule)
    # the same posterior q(x_{t-1} | x_t, x0); the two compute it from float32 constants by different routes
    for ours, ddpm in (("coef_clean", "coef_clean"), ("coef_noisy", "coef_noisy"), ("noise_scale", "noise_scale")):
        torch.testing.assert_close(
            torch.tensor(getattr(strided, ours)), torch.tensor(getattr(every, ddpm)), atol=1e-4, rtol=0
        )
    assert make_sampler("ancestral", schedule, 4, spacing="quadratic").timesteps == [99, 44, 11, 0]


@pytest.mark.parametrize("steps", [5, 10, 20])
@pytest.mark.parametrize("kind", ["linear", "cosine"])
def test_dpmpp2m_matches_diffusers_step_for_step(steps, kind):
    schedule = DiffusionSchedule(ScheduleConfig(kind=kind))
    ours = DPMSolverPP2MSampler(schedule, steps)
    theirs = diffusers.DPMSolverMultistepScheduler(
        **diffusers_kwargs(schedule),
        algorithm_type="dpmsolver++",
        solver_order=2,
        prediction_type="sample",
        lower_order_final=False,
        final_sigmas_type="zero",
    )
    same_alphas(theirs, schedule)
    theirs.set_timesteps(timesteps=ours.timesteps)
    assert theirs.timesteps.tolist() == ours.timesteps
    data = torch.Generator().manual_seed(2)
    x = torch.randn((8, 6), generator=data)
    for index, t in enumerate(ours.timesteps):
        clean = torch.randn((8, 6), generator=data)
        expected = theirs.step(clean.double(), t, x.double()).prev_sample.float()
        x = step(ours, index, x, clean)
        torch.testing.assert_close(x, expected, atol=1e-6, rtol=0)


def reference_loop(solver, targets, sampler_name, steps, num_samples, seed):
    """The plain loop: a new tensor for every state, every condition computed at its step."""
    model = solver.model
    sampler = make_sampler(sampler_name, model.schedule, steps)
    generator = torch.Generator().manual_seed(seed)
    rows = targets.repeat_interleave(num_samples, dim=0)
    x = torch.randn((len(rows), model.representation.dim), generator=generator)
    conditions = step_conditions(model.denoiser, sampler.timesteps, targets, num_samples)
    states = [x]
    with torch.inference_mode():
        for index, t in enumerate(sampler.timesteps):
            output = model.denoiser.denoise(x, rows, conditions[index])
            clean = model.schedule.predict_clean(output, t, x, model.config.prediction)
            if not getattr(model.denoiser, "output_on_manifold", False):
                clean = model.representation.project(clean)
            x = sampler.step(index, x, clean, out=torch.empty_like(x), generator=generator)
            states.append(x)
    return model.representation.decode(torch.stack(states)).unflatten(1, (len(targets), num_samples))


@pytest.mark.parametrize("sampler, steps", [("ddpm", None), ("ddim", 7), ("dpmpp2m", 6), ("ancestral", 5)])
def test_fast_loop_is_bit_identical_to_the_reference(tiny_checkpoint, sampler, steps, monkeypatch):
    # the loop's own buffers change nothing; the compiled step's rounding is tests/test_film_compiled.py's
    monkeypatch.setattr("ikdp.denoisers.film.compiled_workspace", lambda *args: None)
    solver = ikdp.load(tiny_checkpoint)
    targets = torch.tensor([[1.0, 0.5], [0.0, -2.0]])
    out = solver.solve(
        targets,
        num_samples=3,
        sampler=sampler,
        steps=steps,
        generator=torch.Generator().manual_seed(5),
        return_trajectory=True,
    )
    expected = reference_loop(solver, targets, sampler, steps, 3, seed=5)
    assert torch.equal(out.trajectory, expected)
    assert torch.equal(out.raw_angles, expected[-1])


def test_callback_sees_every_step_and_can_stop(tiny_checkpoint):
    solver = ikdp.load(tiny_checkpoint)
    seen = []

    def record(index, timestep, state, estimate):
        seen.append((index, timestep, state.clone(), estimate.clone()))

    out = solver.solve(
        [[1.0, 0.5], [0.0, -2.0]],
        num_samples=4,
        sampler="ddim",
        steps=8,
        return_trajectory=True,
        return_estimates=True,
        callback=record,
        generator=torch.Generator().manual_seed(0),
    )
    assert not out.stopped and out.network_evaluations == 8
    assert [index for index, *_ in seen] == list(range(8)) and [t for _, t, *_ in seen] == out.timesteps
    assert out.estimates.shape == (8, 2, 4, 3) and out.trajectory.shape == (9, 2, 4, 3)
    for index, _, state, estimate in seen:  # the callback's views are the recorded ones
        torch.testing.assert_close(state, out.trajectory[index + 1])
        torch.testing.assert_close(estimate, out.estimates[index])
    torch.testing.assert_close(out.estimates[-1], out.angles)  # DDIM's last step lands on x̂0

    def stop_after_three(index, timestep, state, estimate):
        return index == 2

    stopped = solver.solve(
        [[1.0, 0.5]], num_samples=2, return_trajectory=True, refine_steps=3, callback=stop_after_three
    )
    assert stopped.stopped and stopped.trajectory.shape[0] == 4
    assert stopped.network_evaluations == 3  # steps 0, 1 and 2 ran; the DDPM's other 17 did not
    torch.testing.assert_close(stopped.angles, stopped.trajectory[-1])  # the state reached, not refined
