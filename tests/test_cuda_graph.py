"""The CUDA-graph replay of the reverse loop gives the eager loop's samples (needs CUDA; skipped without it)."""

import pytest
import torch

import ikdp
from ikdp.cuda_graph import CapturedReverseDiffusion
from ikdp.model import IKDiffusion, ModelConfig

needs_cuda = pytest.mark.skipif(not torch.cuda.is_available(), reason="CUDA graphs need a CUDA device")


def test_refuses_a_cpu_model():
    with pytest.raises(ValueError, match="model: expected a model on a CUDA device, got one on cpu"):
        CapturedReverseDiffusion(IKDiffusion(ModelConfig(lengths=(1.0, 1.0))), batch=1, num_samples=2)


@needs_cuda
@pytest.mark.parametrize("sampler, steps", [("ddpm", None), ("ddim", 10), ("dpmpp2m", 10)])
def test_replay_gives_the_eager_samples(sampler, steps):
    solver = ikdp.load("ikdp_n4", device="cuda")
    model = solver.model
    graphed = CapturedReverseDiffusion(model, batch=2, num_samples=16, sampler=sampler, steps=steps)
    for seed, targets in ((0, [[1.5, 1.0], [-0.5, 2.0]]), (7, [[0.0, -3.0], [2.5, 0.5]])):
        targets = torch.tensor(targets, device="cuda")
        eager = model.sample(
            targets,
            num_samples=16,
            sampler=sampler,
            steps=steps,
            generator=torch.Generator("cuda").manual_seed(seed),
            return_trajectory=True,
        )
        replayed = graphed(targets, seed=seed)
        torch.testing.assert_close(replayed.states, eager.states, atol=1e-5, rtol=0)
        torch.testing.assert_close(replayed.headings, eager.headings, atol=1e-5, rtol=0)


@needs_cuda
@pytest.mark.parametrize("name", ["ikdp_n4", "ikdp_panda"])
def test_replay_is_bit_identical_to_the_eager_loop(name):
    """The same kernels on the same inputs: not close, equal (a planar arm and a URDF chain)."""
    solver = ikdp.load(name, device="cuda")
    model = solver.model
    graphed = CapturedReverseDiffusion(model, batch=1, num_samples=16, sampler="dpmpp2m", steps=10)
    targets = solver.arm.end_effector(solver.arm.random_poses(1, generator=torch.Generator().manual_seed(3)))
    targets = targets.to("cuda")
    eager = model.sample(
        targets,
        num_samples=16,
        sampler="dpmpp2m",
        steps=10,
        generator=torch.Generator("cuda").manual_seed(5),
        return_trajectory=True,
    )
    replayed = graphed(targets, seed=5)
    assert torch.equal(replayed.states, eager.states)
