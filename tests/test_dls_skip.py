"""The chain denoiser's DLS skip: the damped least-squares step reaches the estimate through a learned gain."""

import pytest
import torch

import ikdp
from ikdp.denoisers import ChainFiLMDenoiser, DenoiserConfig
from ikdp.model import IKDiffusion, ModelConfig
from ikdp.representation import AngleRepresentation
from ikdp.robots import load_robot
from ikdp.schedule import ScheduleConfig
from ikdp.train import TrainConfig, train


@pytest.fixture(scope="module")
def panda():
    return load_robot("panda")


def skip_model(arm, **denoiser) -> IKDiffusion:
    torch.manual_seed(0)
    config = ModelConfig(
        lengths=(1.0,),
        representation="joints",
        prediction="sample",
        schedule=ScheduleConfig(timesteps=100, kind="karras"),
        denoiser=DenoiserConfig(kind="chain_film", hidden=32, blocks=1, dls_skip=True, **denoiser),
        arm=arm.to_config(),
    )
    return IKDiffusion(config)


def test_the_gain_starts_at_one_at_low_noise_and_zero_at_high_noise(panda):
    start = skip_model(panda).denoiser.step_gain_start
    assert start.shape == (100,)
    assert start[0] > 0.99 and start[-1] < 0.01
    assert bool((start[1:] <= start[:-1]).all())  # falls as the noise rises


def test_the_gains_start_follows_the_recorded_noise_level_where_it_is_one_half(panda):
    for level in (0.1, 0.5):
        model = skip_model(panda, dls_skip_noise=level)
        sigma = model.schedule.noise_levels()
        t = int((sigma - level).abs().argmin())
        expected = 1 / (1 + (sigma[t] / level) ** 2)
        assert abs(float(model.denoiser.step_gain_start[t]) - float(expected)) < 1e-6
        assert 0.3 < float(model.denoiser.step_gain_start[t]) < 0.7
        # what a checkpoint stores rebuilds the same start
        rebuilt = IKDiffusion(ModelConfig.from_dict(model.config.to_dict()))
        assert torch.equal(rebuilt.denoiser.step_gain_start, model.denoiser.step_gain_start)


def test_a_fresh_model_takes_the_solvers_step_at_low_noise_and_shrinks_the_miss(panda):
    model = skip_model(panda)
    representation = model.representation
    generator = torch.Generator().manual_seed(1)
    goal = representation.decode(torch.rand(64, representation.dim, generator=generator) * 1.6 - 0.8)
    targets = panda.end_effector(goal)
    start = goal + 0.05 * torch.randn(goal.shape, generator=generator)  # about 3 degrees off per joint
    with torch.no_grad():
        estimate = model.denoiser(representation.encode(start), torch.zeros(64, dtype=torch.long), targets)
        far = model.denoiser(representation.encode(start), torch.full((64,), 99), targets)
    before = panda.tip_error(start[:, None], targets[:, None]).median()
    after = panda.tip_error(representation.decode(estimate)[:, None], targets[:, None]).median()
    assert after < 0.3 * before
    # at the noisiest step the gain starts near 0: the estimate stays where the MLP (x_t at start) puts it
    assert torch.allclose(far, representation.encode(start), atol=1e-4)


def test_a_chain_denoiser_with_the_skip_needs_the_noise_levels(panda):
    representation = AngleRepresentation("joints", 7, limits=panda.joint_limits, continuous=panda.continuous_joints)
    with pytest.raises(ValueError, match="dls_skip needs the schedule's noise levels"):
        ChainFiLMDenoiser(DenoiserConfig(kind="chain_film", hidden=32, blocks=1, dls_skip=True), representation, panda)


def test_training_with_the_skip_records_it_and_loads_it(tmp_path):
    sizes = dict(steps=6, batch=32, hidden=32, blocks=1, timesteps=8, eval_targets=8, save_every=100, threads=1)
    config = TrainConfig(robot="panda", output=str(tmp_path / "skip.pt"), log_dir=str(tmp_path / "tb"), **sizes)
    solver = ikdp.load(train(config))  # the CPU robot recipe turns it on
    assert solver.model.config.denoiser.dls_skip
    assert solver.model.denoiser.step_gain.weight.abs().sum() > 0  # its change to the gain trained
    out = solver.solve(solver.arm.end_effector(torch.zeros(1, 7)), num_samples=2)
    assert torch.isfinite(out.angles).all()


@pytest.mark.parametrize(
    "changes, message",
    [
        (dict(joints=3, dls_skip=True), "dls_skip: goes with a robot"),
        (dict(robot="panda", dls_skip=True, prediction="epsilon"), "needs --prediction sample"),
        (dict(robot="panda", dls_skip=True, denoiser="mlp"), "dls_skip: goes with a robot"),
    ],
)
def test_the_skip_where_it_has_no_meaning_is_refused(tmp_path, changes, message):
    config = TrainConfig(steps=2, output=str(tmp_path / "x.pt"), log_dir=str(tmp_path / "tb"), **changes)
    with pytest.raises(ValueError, match=message):
        train(config)


def test_the_limit_aware_step_leaves_joints_a_limit_holds_and_misses_less_after_the_clamp(panda):
    generator = torch.Generator().manual_seed(5)
    representation = AngleRepresentation("joints", 7, limits=panda.joint_limits, continuous=panda.continuous_joints)
    lower, upper = panda.joint_limits.unbind(-1)
    goal = lower + (upper - lower) * torch.rand(400, 7, generator=generator)
    goal[:, 3] = torch.where(torch.rand(400, generator=generator) < 0.5, lower[3], upper[3])  # the elbow on a limit
    targets = panda.end_effector(goal)
    start = panda.normalize_joints(goal + 0.03 * torch.randn(goal.shape, generator=generator))
    start[:, 3] = goal[:, 3]  # the other six joints can reach the target with the elbow held where it is
    steps = {}
    for aware in (False, True):
        config = DenoiserConfig(kind="chain_film", hidden=32, blocks=1, limit_aware_step=aware)
        steps[aware] = ChainFiLMDenoiser(config, representation, panda).features_and_step(
            representation.encode(start), targets
        )[1]
    blocked = panda.blocked_by_limits(start, steps[False])
    assert blocked[:, 3].sum() > 50  # the plain step pushes many elbows out
    assert bool((steps[True][blocked] == 0).all())
    rows = blocked.any(-1)
    miss = {
        aware: panda.tip_error(panda.normalize_joints(start + step)[:, None], targets[:, None])[rows, 0]
        for aware, step in steps.items()
    }
    assert miss[True].median() < 0.5 * miss[False].median()
