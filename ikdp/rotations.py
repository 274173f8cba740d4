"""Rotations for spatial arms: URDF roll-pitch-yaw, axis-angle, rotation matrices and quaternions.

Quaternions are (w, x, y, z), scalar first (the convention of IKFlow's tooling), and unit.
Every function is batched over leading dimensions and keeps its input's dtype.
"""

from __future__ import annotations

import torch


def rpy_to_matrix(rpy: torch.Tensor) -> torch.Tensor:
    """URDF roll-pitch-yaw (..., 3) -> rotation (..., 3, 3).

    URDF's rpy are fixed-axis rotations about x, then y, then z: R = Rz(yaw) Ry(pitch) Rx(roll).
    """
    roll, pitch, yaw = rpy.unbind(-1)
    cr, sr = roll.cos(), roll.sin()
    cp, sp = pitch.cos(), pitch.sin()
    cy, sy = yaw.cos(), yaw.sin()
    rows = [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]
    return torch.stack([torch.stack(row, dim=-1) for row in rows], dim=-2)


def skew(vector: torch.Tensor) -> torch.Tensor:
    """(..., 3) -> the cross-product matrix [v]x, (..., 3, 3), so that [v]x w = v x w."""
    x, y, z = vector.unbind(-1)
    zero = torch.zeros_like(x)
    rows = [[zero, -z, y], [z, zero, -x], [-y, x, zero]]
    return torch.stack([torch.stack(row, dim=-1) for row in rows], dim=-2)


def matrix_to_quaternion(matrix: torch.Tensor) -> torch.Tensor:
    """Rotation (..., 3, 3) -> unit quaternion (..., 4), (w, x, y, z) with w >= 0.

    Of the four algebraically equal formulas (one per largest component) each row uses the one
    whose divisor is largest, so no row divides by a number near zero (Shepperd's method).
    """
    m = matrix
    m00, m11, m22 = m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]
    # 4 w^2, 4 x^2, 4 y^2, 4 z^2 from the diagonal; the largest picks the formula.
    squares = torch.stack([1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22], dim=-1)
    candidates = torch.stack(
        [
            torch.stack(
                [
                    squares[..., 0],
                    m[..., 2, 1] - m[..., 1, 2],
                    m[..., 0, 2] - m[..., 2, 0],
                    m[..., 1, 0] - m[..., 0, 1],
                ],
                -1,
            ),
            torch.stack(
                [
                    m[..., 2, 1] - m[..., 1, 2],
                    squares[..., 1],
                    m[..., 1, 0] + m[..., 0, 1],
                    m[..., 0, 2] + m[..., 2, 0],
                ],
                -1,
            ),
            torch.stack(
                [
                    m[..., 0, 2] - m[..., 2, 0],
                    m[..., 1, 0] + m[..., 0, 1],
                    squares[..., 2],
                    m[..., 2, 1] + m[..., 1, 2],
                ],
                -1,
            ),
            torch.stack(
                [
                    m[..., 1, 0] - m[..., 0, 1],
                    m[..., 0, 2] + m[..., 2, 0],
                    m[..., 2, 1] + m[..., 1, 2],
                    squares[..., 3],
                ],
                -1,
            ),
        ],
        dim=-2,
    )  # (..., 4, 4): row i is 2 * q_i * q, exact where q_i is not small
    best = squares.argmax(dim=-1, keepdim=True)  # (..., 1)
    chosen = candidates.gather(-2, best.unsqueeze(-1).expand(*best.shape[:-1], 1, 4)).squeeze(-2)
    quaternion = chosen / chosen.norm(dim=-1, keepdim=True)
    return canonical_quaternion(quaternion)


def canonical_quaternion(quaternion: torch.Tensor) -> torch.Tensor:
    """q and -q are the same rotation: pick the one with w >= 0."""
    return torch.where(quaternion[..., :1] < 0, -quaternion, quaternion)


def quaternion_to_matrix(quaternion: torch.Tensor) -> torch.Tensor:
    """Unit quaternion (..., 4), (w, x, y, z) -> rotation (..., 3, 3)."""
    w, x, y, z = quaternion.unbind(-1)
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]
    return torch.stack([torch.stack(row, dim=-1) for row in rows], dim=-2)


def quaternion_multiply(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Hamilton product a * b of (..., 4) quaternions (w, x, y, z): rotate by b, then by a."""
    aw, ax, ay, az = a.unbind(-1)
    bw, bx, by, bz = b.unbind(-1)
    return torch.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        dim=-1,
    )


def quaternion_conjugate(quaternion: torch.Tensor) -> torch.Tensor:
    """The inverse of a unit quaternion: (w, -x, -y, -z)."""
    # no constant tensor: its host-to-device copy would break CUDA-graph capture
    return torch.cat((quaternion[..., :1], -quaternion[..., 1:]), dim=-1)


def quaternion_to_axis_angle(quaternion: torch.Tensor) -> torch.Tensor:
    """Unit quaternion (..., 4) -> axis * angle (..., 3), angle in [0, pi]: the rotation's log map.

    atan2 of the vector part's norm and |w| is accurate at every angle, and the short way round
    (w >= 0) is taken so the vector's norm is the geodesic angle. Near the identity the factor
    angle / |v| tends to 2, which the small-angle branch uses to stay differentiable there.
    """
    quaternion = canonical_quaternion(quaternion)
    vector = quaternion[..., 1:]
    sine_half = vector.norm(dim=-1, keepdim=True)
    angle = 2 * torch.atan2(sine_half, quaternion[..., :1])
    small = sine_half < 1e-6
    factor = torch.where(
        small, 2 / quaternion[..., :1], angle / torch.where(small, torch.ones_like(sine_half), sine_half)
    )
    return vector * factor


def quaternion_angle(quaternion: torch.Tensor) -> torch.Tensor:
    """The geodesic angle of a unit quaternion's rotation, (...), radians in [0, pi]."""
    return 2 * torch.atan2(quaternion[..., 1:].norm(dim=-1), quaternion[..., 0].abs())


def origin_matrix(origin) -> list[list[float]]:
    """A URDF origin (its `rpy` and `xyz`) as a 4x4 homogeneous matrix (nested lists, float64 maths)."""
    matrix = torch.eye(4, dtype=torch.float64)
    matrix[:3, :3] = rpy_to_matrix(torch.tensor(origin.rpy, dtype=torch.float64))
    matrix[:3, 3] = torch.tensor(origin.xyz, dtype=torch.float64)
    return matrix.tolist()
