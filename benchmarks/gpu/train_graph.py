"""GPU: training steps per second of `ikdp.train`'s three ways to take a step, in one process on one GPU: which
one trains as fast as the hardware allows.

    python -m benchmarks.gpu.train_graph PANDA_URDF       # JSON to $OUT/train_graph.json (else /tmp)
    python -m benchmarks.gpu.train_graph PANDA_URDF cpu   # a dry run on a CPU: the graph row is an error

Rows, for the Panda at the GPU recipe (batch 8192, width 512) and the planar N = 4 recipe (batch 1024):
- `eager, data from the CPU`: the loop before data was made on the device (the baseline): each batch, its
  timesteps and noise drawn on the CPU and copied over;
- `eager, data on the GPU`: EagerSteps as `ikdp.train --device cuda` runs now;
- `graph`: GraphedSteps, `ikdp.train --device cuda` (its default there), each step replayed from one CUDA graph.
Each is warmed up, then timed in `WINDOWS` windows of `STEPS` steps with a synchronize at both ends; the median
window's steps per second is quoted. A last check: the graph's weights after the same steps stay near the
eager ones' (the same data stream; capturable AdamW rounds differently).
"""

from __future__ import annotations

import json
import os
import sys
import traceback
from pathlib import Path

import torch

from benchmarks.gpu.step_rate import steps_per_second
from ikdp.priors import make_prior
from ikdp.train import TrainConfig, TrainingLoss, build_model, with_arm_defaults
from ikdp.train_steps import EagerSteps, GraphedSteps

URDF = sys.argv[1] if len(sys.argv) > 1 else ".gpu/example-robot-data/robots/panda_description/urdf/panda.urdf"
DEVICE = torch.device(sys.argv[2] if len(sys.argv) > 2 else "cuda")
OUT = Path(os.environ.get("OUT", "/tmp")) / "train_graph.json"
STEPS, WINDOWS = int(os.environ.get("STEPS", "100")), int(os.environ.get("WINDOWS", "5"))
ARMS = {
    "panda (GPU recipe)": dict(urdf=URDF, ee_link="panda_hand", device="cuda"),
    "planar N=4": dict(joints=4),
}


def trainer(options: dict, mode: str, seed: int = 0):
    """A fresh model, optimizer and data stream of `options`' recipe, stepping the `mode` way."""
    config = with_arm_defaults(TrainConfig(**options))
    torch.manual_seed(seed)
    model = build_model(config).to(DEVICE)
    prior = make_prior(config.prior, model.arm.num_joints)
    optimizer = torch.optim.AdamW(model.parameters(), lr=config.lr, weight_decay=0.0)
    averaged = torch.optim.swa_utils.AveragedModel(
        model, multi_avg_fn=torch.optim.swa_utils.get_ema_multi_avg_fn(config.ema)
    )
    generator = torch.Generator("cpu" if mode == "eager, data from the CPU" else DEVICE).manual_seed(seed)

    def draw() -> torch.Tensor:
        return prior.sample(config.batch, model.arm, generator=generator).to(DEVICE)

    loss = TrainingLoss(model, config)
    if mode == "graph":
        return GraphedSteps(loss, model, draw, generator, optimizer, averaged, ema=config.ema), model, config
    return EagerSteps(loss, model, draw, generator, optimizer, averaged), model, config


def weights(model) -> torch.Tensor:
    return torch.cat([parameter.detach().flatten() for parameter in model.parameters()])


results: dict = {
    "gpu": torch.cuda.get_device_name(DEVICE) if DEVICE.type == "cuda" else "cpu",
    "torch": torch.__version__,
    "rule": f"median of {WINDOWS} windows of {STEPS} optimizer steps, after 10 warm-up steps",
    "rows": {},
}
for arm_name, options in ARMS.items():
    options = {**options, "device": DEVICE.type}
    for mode in ("eager, data from the CPU", "eager, data on the GPU", "graph"):
        label = f"{arm_name}: {mode}"
        values: dict = {}
        try:
            steps, model, config = trainer(options, mode)
            values = {
                "batch": config.batch,
                "hidden": config.hidden,
                "steps_per_second": steps_per_second(steps, DEVICE, STEPS, WINDOWS),
            }
        except Exception:
            values["error"] = traceback.format_exc()[-1500:]
        results["rows"][label] = values
        OUT.write_text(json.dumps(results, indent=1))
        print(f"{label:48s} {json.dumps(values)}", flush=True)
    try:  # the same 30 steps of the same stream, eager and replayed
        (eager, eager_model, _), (graphed, graphed_model, _) = (
            trainer(options, m) for m in ("eager, data on the GPU", "graph")
        )
        for index in range(30):
            eager(1e-4 * (1 + index % 3))
            graphed(1e-4 * (1 + index % 3))
        difference = float((weights(eager_model) - weights(graphed_model)).abs().max())
        results["rows"][f"{arm_name}: graph vs eager, 30 steps"] = {"max_weight_difference": difference}
    except Exception:
        results["rows"][f"{arm_name}: graph vs eager, 30 steps"] = {"error": traceback.format_exc()[-1500:]}
    OUT.write_text(json.dumps(results, indent=1))
    print(json.dumps(results["rows"][f"{arm_name}: graph vs eager, 30 steps"]), flush=True)
print(f"wrote {OUT}")
