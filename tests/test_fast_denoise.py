"""The FiLM denoiser's fast path: the plain path's numbers bit for bit, and the shipped models' as before."""

import pytest
import torch

import ikdp
from ikdp.arm import PlanarArm
from ikdp.denoisers import DenoiserConfig
from ikdp.model import IKDiffusion, ModelConfig
from ikdp.refine import dls_step, planar_dls_step
from ikdp.sampling import step_conditions


def test_planar_dls_step_is_the_generic_step():
    arm = PlanarArm((1.0, 2.0, 0.5))
    generator = torch.Generator().manual_seed(0)
    headings = torch.randn((6, 3), generator=generator, dtype=torch.float64)
    error = torch.randn((6, 2), generator=generator, dtype=torch.float64)
    positions = arm.forward_kinematics(headings)  # (6, N+1, 2)
    bones = positions[:, 1:] - positions[:, :-1]
    expected = dls_step(arm.jacobian(headings), error, 0.04)
    torch.testing.assert_close(planar_dls_step(bones, error, 0.04), expected, atol=1e-12, rtol=1e-12)


def film_inputs(model, rows, seed, per_row_condition):
    generator = torch.Generator().manual_seed(seed)
    x = torch.randn((rows, model.representation.dim), generator=generator)
    targets = torch.randn((rows, 2), generator=generator)
    timesteps = torch.randint(model.schedule.num_timesteps, (rows if per_row_condition else 1,), generator=generator)
    return x, targets, model.denoiser.condition(timesteps, targets[: len(timesteps)])


@pytest.mark.parametrize("kinematic_until", [0, 30])
@pytest.mark.parametrize("per_row_condition", [False, True])
def test_workspace_path_is_bit_identical_to_the_plain_path(kinematic_until, per_row_condition):
    torch.manual_seed(0)
    config = ModelConfig(lengths=(1.0, 0.5, 2.0), denoiser=DenoiserConfig(hidden=32, blocks=2, kinematic_until=30))
    model = IKDiffusion(config)
    for parameter in model.parameters():  # the output layer starts at zero; give every layer a say
        torch.nn.init.normal_(parameter, std=0.3)
    with torch.inference_mode():
        x, targets, film = film_inputs(model, 7, seed=1, per_row_condition=per_row_condition)
        workspace = model.denoiser.workspace(7, x, compiled=False)  # the torch workspace: bit for bit
        plain = model.denoiser.denoise(x, targets, film)
        for _ in range(2):  # a reused workspace gives the same answer again
            fast = model.denoiser.denoise(x, targets, film, workspace=workspace)
            assert torch.equal(fast, plain)
        assert fast.data_ptr() == workspace.clean.data_ptr()


def test_workspace_is_for_inference_only():
    model = IKDiffusion(ModelConfig(lengths=(1.0, 1.0)))
    assert model.denoiser.workspace(4, torch.zeros(4, 4)) is None  # gradients on: the plain path trains
    with torch.no_grad():
        assert model.denoiser.workspace(4, torch.zeros(4, 4)) is not None
    angle = IKDiffusion(ModelConfig(lengths=(1.0, 1.0), representation="angle"))
    with torch.no_grad():
        assert angle.denoiser.workspace(4, torch.zeros(4, 2)) is None


def previous_denoise(denoiser, x, target, film):
    """The FiLM denoiser as it was before the fast path: the DLS step through batched 2x2 matrix products."""
    unit = denoiser.representation.unit_vectors(x)
    bones = unit * denoiser.lengths[:, None]
    miss = target - bones.sum(dim=-2)
    jacobian = torch.stack((-bones[..., 1], bones[..., 0]), dim=-2)
    features = torch.cat((x, miss, dls_step(jacobian, miss, denoiser.damping_squared)), dim=-1)
    h = denoiser.input(features * film[:, -1, 0, : denoiser.input.in_features])
    for index, block in enumerate(denoiser.blocks):
        h = h + block(torch.nn.functional.silu(torch.addcmul(film[:, index, 1], h, film[:, index, 0])))
    return denoiser.representation.turn(x, denoiser.output(torch.nn.functional.silu(h)), unit=unit)


@pytest.mark.parametrize("name", ["ikdp_n4", "ikdp_n8"])
def test_shipped_models_denoise_as_before(name):
    model = ikdp.load(name).model
    arm = model.arm
    generator = torch.Generator().manual_seed(3)
    targets = arm.end_effector(arm.random_poses(64, generator=generator))
    sampler = model.sampler("ddpm")
    with torch.inference_mode():
        conditions = step_conditions(model.denoiser, sampler.timesteps, targets, 1)
        workspace = model.denoiser.workspace(64, targets)
        for index in (0, 40, 79):  # noisy, halfway, last step
            clean = model.representation.encode(arm.random_poses(64, generator=generator))
            noise = torch.randn(clean.shape, generator=generator)
            x = model.schedule.add_noise(clean, noise, torch.full((64,), sampler.timesteps[index]))
            expected = previous_denoise(model.denoiser, x, targets, conditions[index])
            fast = model.denoiser.denoise(x, targets, conditions[index], workspace=workspace)
            # 5e-5: the compiled kernel (where it builds) sums in another order than torch
            torch.testing.assert_close(fast, expected, atol=5e-5, rtol=0)
