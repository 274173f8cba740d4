import math

import pytest
import torch

from ikdp.denoisers import DenoiserConfig
from ikdp.denoisers.film import DLS_DAMPING
from ikdp.kinematics import tip_jacobian, tip_position, wrap_angle
from ikdp.model import IKDiffusion, ModelConfig
from ikdp.priors import PosePrior
from ikdp.representation import AngleRepresentation
from ikdp.schedule import ScheduleConfig


@pytest.mark.parametrize("kind", ["angle", "cossin"])
def test_representation_round_trip(kind):
    representation = AngleRepresentation(kind, 3)
    headings = torch.tensor([[math.pi, -0.5, 2.0]])
    decoded = representation.decode(representation.encode(headings))
    torch.testing.assert_close(wrap_angle(decoded - headings), torch.zeros(1, 3), atol=1e-6, rtol=0)
    assert representation.encode(headings).shape == (1, representation.dim)


def test_cossin_is_wrap_free():
    representation = AngleRepresentation("cossin", 1)
    near_pi = representation.encode(torch.tensor([[math.pi - 0.01], [-math.pi + 0.01]]))
    assert (near_pi[0] - near_pi[1]).norm() < 0.03  # the same heading, nearby vectors
    angle = AngleRepresentation("angle", 1).encode(torch.tensor([[math.pi - 0.01], [-math.pi + 0.01]]))
    assert (angle[0] - angle[1]).norm() > 1.9  # the paper's raw theta puts them far apart


def test_film_features_are_tip_miss_and_dls_step():
    model = IKDiffusion(ModelConfig(lengths=(1.0, 2.0, 0.5)))
    headings, targets = torch.randn(5, 3), torch.randn(5, 2)
    x = model.representation.encode(headings)
    features = model.denoiser.features(x, model.representation.unit_vectors(x), targets)
    miss = targets - tip_position(headings, model.lengths)
    torch.testing.assert_close(features[:, 6:8], miss, atol=1e-5, rtol=0)
    jacobian = tip_jacobian(headings, model.lengths)
    damped = jacobian @ jacobian.transpose(-1, -2) + (DLS_DAMPING * 3.5) ** 2 * torch.eye(2)
    expected = (jacobian.transpose(-1, -2) @ torch.linalg.solve(damped, miss[..., None]))[..., 0]
    torch.testing.assert_close(features[:, 8:], expected, atol=1e-4, rtol=1e-4)


def test_kinematic_features_switch_off_above_kinematic_until():
    config = ModelConfig(lengths=(1.0,) * 3, denoiser=DenoiserConfig(kinematic_until=30))
    denoiser = IKDiffusion(config).denoiser
    targets = torch.randn(2, 2)
    scales = denoiser.condition(torch.tensor([29, 30]), targets)[:, -1, 0, : denoiser.input.in_features]
    torch.testing.assert_close(scales[0], denoiser.feature_scale)  # t < 30: every feature
    assert (scales[1, :6] == 1).all() and (scales[1, 6:] == 0).all()  # t >= 30: x_t only


@pytest.mark.parametrize("kind", ["angle", "cossin"])
def test_turn_adds_to_the_headings(kind):
    representation = AngleRepresentation(kind, 3)
    headings, turn = torch.tensor([[0.1, 2.0, -3.0]]), torch.tensor([[0.5, -0.2, 0.3]])
    turned = representation.decode(representation.turn(representation.encode(headings), turn))
    torch.testing.assert_close(turned, wrap_angle(headings + turn))


@pytest.mark.parametrize("denoiser", ["film", "paper"])
@pytest.mark.parametrize("representation", ["angle", "cossin"])
def test_sample_shapes(denoiser, representation):
    config = ModelConfig(
        lengths=(1.0,) * 3,
        representation=representation,
        schedule=ScheduleConfig(timesteps=10),
        denoiser=DenoiserConfig(kind=denoiser, hidden=16, model_dim=16),
    )
    model = IKDiffusion(config).eval()
    result = model.sample(torch.tensor([[1.0, 1.0], [0.0, -2.0]]), num_samples=5, return_trajectory=True)
    assert result.headings.shape == (2, 5, 3)
    assert result.states.shape == (11, 2, 5, 3)
    torch.testing.assert_close(result.states[-1], result.headings)
    assert (result.headings.abs() <= math.pi).all()
    ddim = model.sample(torch.tensor([[1.0, 1.0]]), num_samples=2, sampler="ddim", steps=4, return_trajectory=True)
    assert ddim.states.shape == (5, 1, 2, 3) and len(ddim.timesteps) == 4


def test_ddim_with_all_steps_is_deterministic():
    model = IKDiffusion(ModelConfig(schedule=ScheduleConfig(timesteps=12), denoiser=DenoiserConfig(hidden=16))).eval()
    targets = torch.tensor([[1.0, 2.0]])
    first = model.sample(targets, num_samples=3, sampler="ddim", generator=torch.Generator().manual_seed(5))
    second = model.sample(targets, num_samples=3, sampler="ddim", generator=torch.Generator().manual_seed(5))
    torch.testing.assert_close(first.headings, second.headings, rtol=0, atol=0)
    other = model.sample(targets, num_samples=3, sampler="ddim", generator=torch.Generator().manual_seed(6))
    assert not torch.equal(first.headings, other.headings)  # the only randomness is theta_T


def test_precomputed_and_per_step_conditions_agree(monkeypatch):
    import ikdp.sampling

    model = IKDiffusion(ModelConfig(schedule=ScheduleConfig(timesteps=8), denoiser=DenoiserConfig(hidden=16))).eval()
    targets = torch.tensor([[1.0, 2.0], [-1.0, 0.5]])
    batched = model.sample(targets, num_samples=3, generator=torch.Generator().manual_seed(0))
    monkeypatch.setattr(ikdp.sampling, "PRECOMPUTE_CONDITION_LIMIT", 0)
    stepwise = model.sample(targets, num_samples=3, generator=torch.Generator().manual_seed(0))
    torch.testing.assert_close(batched.headings, stepwise.headings)


def test_ddpm_refuses_a_step_count():
    model = IKDiffusion(ModelConfig(schedule=ScheduleConfig(timesteps=8))).eval()
    with pytest.raises(ValueError, match="steps"):
        model.sample(torch.zeros(1, 2), steps=4)
    with pytest.raises(ValueError, match="sampler"):
        model.sample(torch.zeros(1, 2), sampler="euler")


@pytest.mark.parametrize("denoiser", ["film", "paper"])
def test_loss_goes_down(denoiser):
    torch.manual_seed(0)
    config = ModelConfig(
        lengths=(1.0, 1.0),
        schedule=ScheduleConfig(timesteps=20),
        denoiser=DenoiserConfig(kind=denoiser, hidden=64, model_dim=32, mlp_hidden=64, layers=1),
    )
    model = IKDiffusion(config)
    optimizer = torch.optim.Adam(model.parameters(), lr=3e-3)
    generator = torch.Generator().manual_seed(0)
    prior = PosePrior()
    losses = []
    for _ in range(200):
        loss = model.compute_loss(prior.sample(256, 2, generator=generator), tip_loss_weight=1.0, generator=generator)
        optimizer.zero_grad()
        loss["loss"].backward()
        optimizer.step()
        losses.append(float(loss["theta_loss"]))
    assert sum(losses[-20:]) / 20 < 0.8 * sum(losses[:20]) / 20
