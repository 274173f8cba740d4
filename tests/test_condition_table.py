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


def test_the_few_target_trunk_is_the_modules_own(tiny_chain_checkpoint):
    denoiser = ikdp.load(tiny_chain_checkpoint).model.denoiser
    with torch.no_grad():  # every weight drawn: a barely trained output layer would hide the trunk
        generator = torch.Generator().manual_seed(5)
        for parameter in denoiser.parameters():
            parameter.copy_(0.3 * torch.randn(parameter.shape, generator=generator))
    arm = denoiser.arm
    targets = arm.end_effector(arm.random_poses(2, generator=torch.Generator().manual_seed(3)))
    x = torch.randn(2 * 5, denoiser.representation.dim, generator=torch.Generator().manual_seed(4))
    t = torch.tensor([6, 2])
    with torch.no_grad():
        film = denoiser.condition(t, targets)  # builds the table, and with it the trunk's weights
        trunk = denoiser.denoise(x, targets, film)
        assert denoiser.condition_table.layers
        table, denoiser.condition_table = denoiser.condition_table, None  # the modules' own path
        own = denoiser.denoise(x, targets, film)
        denoiser.condition_table = table
        with torch.no_grad():
            denoiser.blocks[0].bias.add_(0.25)  # a changed weight: the trunk steps aside until rebuilt
        changed = denoiser.denoise(x, targets, film)
        denoiser.condition_table = None
        changed_own = denoiser.denoise(x, targets, film)
    assert not torch.equal(trunk, own)  # two computations, not one path run twice
    torch.testing.assert_close(trunk, own, atol=1e-5, rtol=1e-5)
    torch.testing.assert_close(changed, changed_own, atol=0, rtol=0)
