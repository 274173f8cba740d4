"""Forward kinematics of 100,000 Panda poses: ChainArm against pytorch_kinematics, in the same run.

    python benchmarks/chain_fk.py

One torch thread, float32, the same joint values for both; median of `repeats` runs after a
warm-up. Rows: ChainArm's end-effector frame (rotation matrix + position: what training needs
before the features), its pose with the quaternion, and pytorch_kinematics' `forward_kinematics`
of the serial chain to `panda_hand` (a 4x4 per pose). The largest difference between the two
positions is printed beside the times so a fast wrong answer cannot pass unnoticed. Writes
benchmarks/results/chain_fk.json. pytorch_kinematics is the reference here, not a dependency.
"""

from __future__ import annotations

import json
import os
import platform
import statistics
import time
from dataclasses import dataclass
from importlib.metadata import version
from pathlib import Path

import torch
import tyro

from ikdp.robots import ROBOTS, example_robot_data_file, load_robot


@dataclass(frozen=True)
class ChainFkConfig:
    poses: int = 100_000  # Panda poses per FK call
    repeats: int = 7  # timed calls per method (median quoted)


def median_seconds(function, repeats: int) -> float:
    function()  # warm-up
    seconds = []
    for _ in range(repeats):
        started = time.perf_counter()
        function()
        seconds.append(time.perf_counter() - started)
    return statistics.median(seconds)


def main(config: ChainFkConfig) -> None:
    import pytorch_kinematics as pk

    torch.set_num_threads(1)
    arm = load_robot("panda")
    urdf_text = example_robot_data_file(ROBOTS["panda"].urdf).read_text()
    chain = pk.build_serial_chain_from_urdf(urdf_text, "panda_hand")
    joints = arm.random_poses(config.poses, generator=torch.Generator().manual_seed(0))  # (poses, 7) float32

    difference = (chain.forward_kinematics(joints).get_matrix()[:, :3, 3] - arm.end_effector_frame(joints)[1]).abs()
    cases = {
        "ChainArm.end_effector_frame": lambda: arm.end_effector_frame(joints),
        "ChainArm.end_effector_pose (+ quaternion)": lambda: arm.end_effector_pose(joints),
        "pytorch_kinematics forward_kinematics": lambda: chain.forward_kinematics(joints).get_matrix(),
    }
    print(f"FK of {config.poses:,} Panda poses to panda_hand, float32, median of {config.repeats}, torch threads = 1")
    print(f"largest position difference between the two: {float(difference.max()):.2e} m\n")
    print("| method | median ms | vs pytorch_kinematics |\n|---|---|---|")
    timings = {name: median_seconds(function, config.repeats) for name, function in cases.items()}
    reference = timings["pytorch_kinematics forward_kinematics"]
    rows = []
    for name, seconds in timings.items():
        rows.append({"method": name, "median_ms": round(1000 * seconds, 2), "speedup": round(reference / seconds, 2)})
        print(f"| {name} | {1000 * seconds:.1f} | {reference / seconds:.1f}x |")
    output = Path("benchmarks/results/chain_fk.json")
    output.parent.mkdir(parents=True, exist_ok=True)
    output.write_text(
        json.dumps(
            {
                "poses": config.poses,
                "repeats": config.repeats,
                "threads": 1,
                "dtype": "float32",
                "max_position_difference_m": float(difference.max()),
                "torch": str(torch.__version__),
                "pytorch_kinematics": version("pytorch_kinematics"),
                "machine": platform.machine(),
                "load_average_1min": os.getloadavg()[0],  # the machine is shared: a busy one slows every row
                "date": time.strftime("%Y-%m-%d"),
                "rows": rows,
            },
            indent=2,
        )
        + "\n"
    )


if __name__ == "__main__":
    main(tyro.cli(ChainFkConfig, description=__doc__.splitlines()[0]))
