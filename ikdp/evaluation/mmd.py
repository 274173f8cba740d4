"""Maximum mean discrepancy between two sets of poses of one target (Gretton et al. 2012).

A pose is embedded as its (cos theta, sin theta) per link, 2N numbers, so the
kernel sees headings on the circle, free of the wrap at pi. The kernel is the
mean of Gaussian kernels exp(-||x - y||^2 / (2 s^2)) over the bandwidths
BANDWIDTHS (in the units of that embedding; turning one link by a small angle
d moves it by about d). We use the biased (V-statistic) MMD^2: it is never
negative, and two independent sets drawn from one distribution give a positive
"noise floor" that depends only on the set sizes, which we measure and print.
"""

from __future__ import annotations

import torch

BANDWIDTHS = (0.1, 0.2, 0.5, 1.0, 2.0)
KERNEL_DESCRIPTION = "mean of Gaussian RBF kernels on (cos, sin) of every link heading, bandwidths " + ", ".join(
    f"{bandwidth:g}" for bandwidth in BANDWIDTHS
)


def pose_features(headings: torch.Tensor) -> torch.Tensor:
    """(..., N) headings -> (..., 2N) embedding."""
    return torch.cat((torch.cos(headings), torch.sin(headings)), dim=-1).double()


def kernel(x: torch.Tensor, y: torch.Tensor, bandwidths=BANDWIDTHS) -> torch.Tensor:
    """x (..., m, D), y (..., n, D) -> (..., m, n)."""
    squared = torch.cdist(x, y).pow(2)
    return torch.stack([torch.exp(-squared / (2 * bandwidth**2)) for bandwidth in bandwidths]).mean(0)


def mmd2(samples: torch.Tensor, reference: torch.Tensor, bandwidths=BANDWIDTHS) -> torch.Tensor:
    """Biased MMD^2 per target between headings (B, m, N) and (B, n, N) -> (B,)."""
    x, y = pose_features(samples), pose_features(reference)
    return (
        kernel(x, x, bandwidths).mean(dim=(-1, -2))
        + kernel(y, y, bandwidths).mean(dim=(-1, -2))
        - 2 * kernel(x, y, bandwidths).mean(dim=(-1, -2))
    )
