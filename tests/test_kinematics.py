import math

import pytest
import torch

from ikdp.kinematics import (
    absolute_to_relative,
    forward_kinematics,
    project_to_workspace,
    reach,
    relative_to_absolute,
    tip_jacobian,
    tip_position,
    wrap_angle,
)


def test_forward_kinematics_closed_form():
    # two unit links: first along +x, second straight up
    joints = forward_kinematics(torch.tensor([0.0, math.pi / 2]))
    assert joints.shape == (3, 2)
    torch.testing.assert_close(joints, torch.tensor([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]), atol=1e-6, rtol=0)


def test_forward_kinematics_with_lengths_and_batch():
    headings = torch.tensor([[0.0, math.pi, math.pi / 2]]).repeat(5, 1)
    joints = forward_kinematics(headings, lengths=[2.0, 0.5, 3.0])
    assert joints.shape == (5, 4, 2)
    torch.testing.assert_close(joints[0, -1], torch.tensor([1.5, 3.0]), atol=1e-6, rtol=0)
    torch.testing.assert_close(tip_position(headings, [2.0, 0.5, 3.0]), joints[:, -1], atol=1e-6, rtol=0)


def test_lengths_of_wrong_size_are_refused():
    with pytest.raises(ValueError, match="lengths"):
        forward_kinematics(torch.zeros(3), lengths=[1.0, 1.0])


def test_jacobian_matches_autograd():
    torch.manual_seed(0)
    headings = torch.randn(4, dtype=torch.float64)
    lengths = torch.tensor([1.0, 0.7, 1.3, 0.4], dtype=torch.float64)
    expected = torch.autograd.functional.jacobian(lambda h: tip_position(h, lengths), headings)
    torch.testing.assert_close(tip_jacobian(headings, lengths), expected)


def test_relative_absolute_round_trip():
    torch.manual_seed(1)
    headings = wrap_angle(torch.randn(100, 6) * 3)
    torch.testing.assert_close(relative_to_absolute(absolute_to_relative(headings)), headings, atol=1e-5, rtol=0)
    # a straight arm bent only at the second joint
    relative = torch.tensor([0.3, 0.0, 1.0])
    torch.testing.assert_close(relative_to_absolute(relative), torch.tensor([0.3, 0.3, 1.3]))


def test_wrap_angle_range():
    wrapped = wrap_angle(torch.tensor([math.pi, -math.pi, 3 * math.pi, 0.5, -7.0]))
    assert (wrapped > -math.pi).all() and (wrapped <= math.pi).all()
    torch.testing.assert_close(wrapped[:2], torch.tensor([math.pi, math.pi]))
    torch.testing.assert_close(torch.cos(wrapped), torch.cos(torch.tensor([math.pi, -math.pi, 3 * math.pi, 0.5, -7.0])))


def test_reach_and_projection():
    assert reach([1, 1, 1, 1]) == (0.0, 4.0)
    assert reach([3, 1]) == (2.0, 4.0)
    projected = project_to_workspace(torch.tensor([[10.0, 0.0], [0.5, 0.0], [1.0, 1.0]]), [3.0, 1.0])
    torch.testing.assert_close(
        projected, torch.tensor([[4.0, 0.0], [2.0, 0.0], [1.0, 1.0]]) * torch.tensor([[1.0], [1.0], [2 / math.sqrt(2)]])
    )
