"""pytorch_kinematics' batched PseudoInverseIK on the planar N-link arm: the reference IK library.

The arm becomes a URDF string: N continuous joints about z, bone n along the x
axis of its link, and a fixed `tip` frame at the end of the last bone. Its joint
values are relative joint angles; the absolute link headings are their cumsum.

The goal is position only, in the two ways PseudoInverseIK allows:
`orientation_weight=0` zeroes the three rotation rows of the Jacobian and of the
pose error in its damped least-squares step, so the orientation never pulls the
solution, and `rot_tolerance=inf` lets a retry count as converged on position
alone. The goal itself is Transform3d(pos=(x, y, 0)) with the identity rotation,
which the two settings make irrelevant.

pytorch_kinematics is not an IKDP dependency: it lives in the benchmark's own
environment (benchmarks/requirements-bench.txt). solver_benchmark.py runs this
file there as a subprocess,

    benchmarks/.venv-pk/bin/python -m benchmarks.pk_chain REQUEST.pt RESULT.pt

which keeps the library's import out of the process that times IKDP. This file
imports torch and, inside `solve_timed`, pytorch_kinematics; never ikdp.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import asdict, dataclass
from importlib.metadata import version

import torch


@dataclass(frozen=True)
class PkSettings:
    max_iterations: int = 50  # PseudoInverseIK's default
    pos_tolerance: float = 1e-4  # the benchmark's success threshold, in bone lengths
    lr: float = 1.0  # step size, its default
    lm_damping: float = 0.1  # error-proportional Levenberg-Marquardt damping, its default
    regularization: float = 1e-9  # lambda^2 of its damped least squares, its default
    early_stopping_any_converged: bool = True  # drop a target once one retry converged: success is "one of K"
    early_stopping_no_improvement: str = "any"  # its default: drop a target when its retries stop improving
    early_stopping_no_improvement_patience: int = 2  # its default


def planar_urdf(lengths: list[float]) -> str:
    """A planar serial arm: joint n turns about z at the end of bone n-1; the `tip` frame ends bone N."""
    lines = ['<robot name="planar_arm">', '  <link name="base"/>']
    parent, offset = "base", 0.0
    for index, length in enumerate(lengths):
        lines += [
            f'  <link name="link{index}"/>',
            f'  <joint name="joint{index}" type="continuous">',
            f'    <parent link="{parent}"/><child link="link{index}"/>',
            f'    <origin xyz="{offset!r} 0 0"/><axis xyz="0 0 1"/>',
            "  </joint>",
        ]
        parent, offset = f"link{index}", float(length)
    lines += [
        '  <link name="tip"/>',
        '  <joint name="tip_joint" type="fixed">',
        f'    <parent link="{parent}"/><child link="tip"/><origin xyz="{offset!r} 0 0"/>',
        "  </joint>",
        "</robot>",
    ]
    return "\n".join(lines)


def solve_timed(
    targets: torch.Tensor,
    lengths: list[float],
    retry_configs: torch.Tensor,
    settings: PkSettings,
    *,
    repeats: int,
    warmup: int,
) -> dict:
    """targets: (B, 2), retry_configs: (R, N) starts shared by every target -> seconds per solve and the last answer.

    The timed call builds the goal transforms and runs `solve`; the chain and the
    solver object are built once, as a user would.
    """
    import pytorch_kinematics as pk

    chain = pk.build_serial_chain_from_urdf(planar_urdf(lengths), "tip")
    solver = pk.PseudoInverseIK(
        chain,
        retry_configs=retry_configs,
        max_iterations=settings.max_iterations,
        pos_tolerance=settings.pos_tolerance,
        rot_tolerance=math.inf,
        orientation_weight=0.0,
        lr=settings.lr,
        lm_damping=settings.lm_damping,
        regularlization=settings.regularization,  # sic: the library's spelling
        early_stopping_any_converged=settings.early_stopping_any_converged,
        early_stopping_no_improvement=settings.early_stopping_no_improvement,
        early_stopping_no_improvement_patience=settings.early_stopping_no_improvement_patience,
    )
    goal_xyz = torch.nn.functional.pad(targets.float(), (0, 1))  # (B, 3), z = 0

    def solve():
        return solver.solve(pk.Transform3d(pos=goal_xyz))

    for _ in range(warmup):
        solve()
    seconds = []
    for _ in range(repeats):
        start = time.perf_counter()
        solution = solve()
        seconds.append(time.perf_counter() - start)
    return {
        "seconds": seconds,
        "joint_angles": solution.solutions.detach().clone(),  # (B, R, N) relative joint angles
        "converged_any": solution.converged_any.detach().clone(),  # (B,) its own verdict
        "iterations": solution.iterations,
        "library_version": version("pytorch_kinematics"),
        "torch_version": torch.__version__.split("+")[0],
        "dtype": str(chain.dtype),
    }


def main(argv: list[str] | None = None) -> None:
    request_path, result_path = argv if argv is not None else sys.argv[1:]
    request = torch.load(request_path, weights_only=True)
    torch.set_num_threads(request["threads"])
    result = solve_timed(
        request["targets"],
        request["lengths"],
        request["retry_configs"],
        PkSettings(**request["settings"]),
        repeats=request["repeats"],
        warmup=request["warmup"],
    )
    result["settings"] = asdict(PkSettings(**request["settings"]))
    result["threads"] = torch.get_num_threads()
    torch.save(result, result_path)


if __name__ == "__main__":
    main()
