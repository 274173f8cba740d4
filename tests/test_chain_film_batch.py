"""The robot denoiser's batch path: one condition per target broadcast over its rows, large batches in chunks,
and int8 weights for CPU sampling (ikdp.load(..., precision="int8"))."""

import pytest
import torch

import ikdp
from ikdp.denoisers import DenoiserConfig, chain_film
from ikdp.model import IKDiffusion, ModelConfig
from ikdp.robots import load_robot
from ikdp.sampling import run_reverse_diffusion


@pytest.fixture(scope="module")
def panda():
    return load_robot("panda")


def chain_model(arm, dls_skip: bool = False) -> IKDiffusion:
    torch.manual_seed(0)
    config = ModelConfig(
        lengths=(1.0,),
        representation="joints",
        denoiser=DenoiserConfig(kind="chain_film", hidden=64, blocks=2, dls_skip=dls_skip),
        arm=arm.to_config(),
    )
    model = IKDiffusion(config)
    for parameter in model.parameters():  # the output layer starts at zero; give every layer a say
        torch.nn.init.normal_(parameter, std=0.2)
    return model.eval()


def inputs(model, arm, targets: int, per_target: int):
    generator = torch.Generator().manual_seed(1)
    goals = arm.end_effector(arm.random_poses(targets, generator=generator))
    x = torch.randn((targets * per_target, model.representation.dim), generator=generator)
    t = torch.randint(model.schedule.num_timesteps, (targets,), generator=generator)
    return x, goals, model.denoiser.condition(t, goals)


@pytest.mark.parametrize("dls_skip", [False, True])
def test_a_condition_per_target_gives_what_a_condition_per_row_gives(panda, dls_skip):
    model = chain_model(panda, dls_skip)
    with torch.no_grad():
        x, goals, film = inputs(model, panda, targets=5, per_target=4)
        per_row = model.denoiser.denoise(x, goals.repeat_interleave(4, 0), film.repeat_interleave(4, 0))
        per_target = model.denoiser.denoise(x, goals, film)
    torch.testing.assert_close(per_target, per_row, atol=1e-6, rtol=1e-5)
    assert float((per_row - x).abs().mean()) > 1e-3  # the network did something to compare


def test_a_large_batch_in_chunks_gives_what_one_pass_gives(panda, monkeypatch):
    model = chain_model(panda)
    with torch.no_grad():
        x, goals, film = inputs(model, panda, targets=7, per_target=3)
        whole = model.denoiser.denoise(x, goals, film)
        monkeypatch.setattr(chain_film, "SAMPLING_CHUNK_ROWS", 6)  # two targets a chunk, and one left over
        chunked = model.denoiser.denoise(x, goals, film)
    torch.testing.assert_close(chunked, whole, atol=1e-6, rtol=1e-5)


def test_rows_that_cannot_share_the_conditions_are_refused(panda):
    model = chain_model(panda)
    with torch.no_grad():
        x, goals, film = inputs(model, panda, targets=3, per_target=2)
        with pytest.raises(ValueError, match="cannot share 3 conditions"):
            model.denoiser.denoise(x[:5], goals, film)


def test_the_sampling_loop_hands_the_chain_denoiser_one_condition_per_target(panda, monkeypatch):
    model = chain_model(panda)
    seen = []
    denoise = model.denoiser.denoise
    monkeypatch.setattr(
        model.denoiser, "denoise", lambda x, target, film: seen.append(len(film)) or denoise(x, target, film)
    )
    generator = torch.Generator().manual_seed(2)
    goals = panda.end_effector(panda.random_poses(3, generator=generator))
    with torch.no_grad():
        run_reverse_diffusion(
            model.denoiser,
            model.schedule,
            model.representation,
            model.sampler("ddim", steps=3),
            goals,
            num_samples=4,
            prediction=model.config.prediction,
            generator=generator,
        )
    assert seen == [3, 3, 3]


@pytest.fixture(scope="module")
def panda_file():
    return "ikdp_panda_fast"  # a shipped Panda model, 256 wide: small enough for a fast test


def test_int8_weights_sample_close_to_the_float_weights(panda, panda_file):
    exact = ikdp.load(panda_file)
    quantized = ikdp.load(panda_file, precision="int8")
    assert quantized.metadata["precision"] == "int8" and exact.metadata["precision"] == "float32"
    assert quantized.model.denoiser.int8 is not None and exact.model.denoiser.int8 is None
    goals = panda.end_effector(panda.random_poses(64, generator=torch.Generator().manual_seed(3)))
    solves = [
        solver.solve(goals, num_samples=2, sampler="ddim", steps=4, generator=torch.Generator().manual_seed(4))
        for solver in (exact, quantized)
    ]
    moved = (solves[0].angles - solves[1].angles).abs()
    spread = (solves[0].angles - solves[0].angles.mean(dim=(0, 1))).abs().mean()
    assert 0 < float(moved.mean()) < 0.1 * float(spread)  # int8 changes the samples, and only a little
    assert exact.model.denoiser.trunk_layers() is exact.model.denoiser.blocks  # the float model keeps its own


def test_an_int8_pose_does_not_depend_on_the_targets_solved_beside_it(panda, panda_file):
    quantized = ikdp.load(panda_file, precision="int8")
    goals = panda.end_effector(panda.random_poses(32, generator=torch.Generator().manual_seed(5)))
    noise = torch.randn(32, 4, quantized.noise_dim, generator=torch.Generator().manual_seed(6))
    options = {"num_samples": 4, "sampler": "ddim", "steps": 2}
    together = quantized.solve(goals, initial_noise=noise, **options).raw_angles
    for index in (0, 17, 31):  # alone, each gets the pose it got among the 32 (batch-scaled inputs: 0.2 rad apart)
        alone = quantized.solve(goals[index : index + 1], initial_noise=noise[index : index + 1], **options)
        # Float32 products may take another kernel for another batch size (1e-6 rad apart on an Intel Xeon, equal
        # on an AMD EPYC), so the pose is held to float rounding, not to the bit.
        torch.testing.assert_close(alone.raw_angles[0], together[index], atol=1e-4, rtol=0)


def test_int8_is_refused_in_one_line_where_it_cannot_run(panda_file):
    with pytest.raises(ValueError, match=r"precision: expected one of \('float32', 'int8'\), got 'fp8'"):
        ikdp.load(panda_file, precision="fp8")
    with pytest.raises(ValueError, match="built for the robots' 'chain_film' denoiser; ikdp_n4.pt has 'film'"):
        ikdp.load("ikdp_n4", precision="int8")
