"""The robot denoiser's condition for a few targets without gradients (ikdp/denoisers/condition_table.py) is the
one its full computation gives, and follows its weights when they change."""

import torch

import ikdp


def conditions_both_ways(denoiser, t, targets):
    with torch.no_grad():
        table = denoiser.condition(t, targets)
    full = denoiser.condition(t, targets).detach()  # with gradients: the full computation
    return table, full


def test_the_tables_condition_is_the_full_one(tiny_chain_checkpoint):
    denoiser = ikdp.load(tiny_chain_checkpoint).model.denoiser
    arm = denoiser.arm
    targets = arm.end_effector(arm.random_poses(3, generator=torch.Generator().manual_seed(1)))
    t = torch.tensor([9, 4, 0])
    table, full = conditions_both_ways(denoiser, t, targets)
    assert denoiser.condition_table is not None and denoiser.condition_table.count == 10
    assert table.shape == full.shape
    torch.testing.assert_close(table, full, atol=1e-5, rtol=1e-5)


def test_the_table_follows_a_changed_weight(tiny_chain_checkpoint):
    denoiser = ikdp.load(tiny_chain_checkpoint).model.denoiser
    arm = denoiser.arm
    targets = arm.end_effector(arm.random_poses(2, generator=torch.Generator().manual_seed(2)))
    t = torch.tensor([3, 1])
    before, _ = conditions_both_ways(denoiser, t, targets)
    with torch.no_grad():
        denoiser.condition_net[0].bias.add_(0.5)  # an optimizer's in-place update
    after, full = conditions_both_ways(denoiser, t, targets)
    assert not torch.allclose(after, before)
    torch.testing.assert_close(after, full, atol=1e-5, rtol=1e-5)
