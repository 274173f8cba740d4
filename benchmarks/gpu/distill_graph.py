"""GPU: steps per second of `ikdp.distill`'s one-step recipe, eager against one CUDA graph a step, in one process.

    python -m benchmarks.gpu.distill_graph                # the shipped ikdp_panda as teacher; JSON to $OUT
    python -m benchmarks.gpu.distill_graph ikdp_n4 cpu    # a dry run on a CPU: the graph row is an error

The recipe of the one-step students (docs/training.md, "Few-step students": no match term, the distribution term
against a pool of the teacher's refined DDPM samples, the FK miss as a distance), batch 1024 of 256 targets × 4
noises, the student predicting the pose itself. Rows: `eager` (EagerSteps: the data drawn on the GPU, op by op)
and `graph` (GraphedSteps: `ikdp.distill --device cuda`'s default for this recipe). Each warmed up, then timed in
`WINDOWS` windows of `STEPS` steps with a synchronize at both ends; the median window's rate is quoted. Then the
weights' largest difference after the same 30 steps of the same stream.
"""

from __future__ import annotations

import json
import os
import sys
import traceback
from pathlib import Path

import torch

import ikdp
from benchmarks.gpu.step_rate import steps_per_second
from ikdp.checkpoint import read_checkpoint
from ikdp.distill import DistillConfig, student_network
from ikdp.distill_reference import PoseStream
from ikdp.distill_step import DistillLoss, student_sampler
from ikdp.train_steps import EagerSteps, GraphedSteps

TEACHER = sys.argv[1] if len(sys.argv) > 1 else "ikdp_panda"
DEVICE = torch.device(sys.argv[2] if len(sys.argv) > 2 else "cuda")
OUT = Path(os.environ.get("OUT", "/tmp")) / "distill_graph.json"
STEPS, WINDOWS = int(os.environ.get("STEPS", "50")), int(os.environ.get("WINDOWS", "3"))
CONFIG = DistillConfig(
    teacher=TEACHER,
    student_steps=1,
    student_prediction="sample",
    batch=1024,
    noises_per_target=4,
    match_weight=0.0,
    distribution_weight=10.0,
    reference_pool=int(os.environ.get("POOL", "4096")),
    refine_reference_steps=3,
    tip_loss_weight=0.0,
    tip_distance_weight=60.0,
)

solver = ikdp.load(TEACHER, device=DEVICE)
path = solver.metadata["path"]
stream = PoseStream(solver.model, solver.prior, CONFIG, DEVICE)  # the pool: drawn once, shared by every row


def runner(kind):
    """A fresh student of the teacher, its optimizer and data stream, stepping the `kind` way."""
    torch.manual_seed(0)
    student = student_network(read_checkpoint(path), path, False, CONFIG.student_prediction).to(DEVICE)
    loss = DistillLoss(student, solver.model, student_sampler(student, CONFIG), CONFIG)
    generator = torch.Generator(DEVICE).manual_seed(0)
    optimizer = torch.optim.AdamW(student.parameters(), lr=CONFIG.lr, weight_decay=0.0)
    return kind(loss, student, lambda: stream.draw(generator), generator, optimizer), student


results: dict = {
    "gpu": torch.cuda.get_device_name(DEVICE) if DEVICE.type == "cuda" else "cpu",
    "torch": torch.__version__,
    "teacher": TEACHER,
    "rule": f"median of {WINDOWS} windows of {STEPS} steps, after 10 warm-up steps; batch {CONFIG.batch}",
    "rows": {},
}
for name, kind in (("eager", EagerSteps), ("graph", GraphedSteps)):
    try:
        results["rows"][name] = {"steps_per_second": steps_per_second(runner(kind)[0], DEVICE, STEPS, WINDOWS)}
    except Exception:
        results["rows"][name] = {"error": traceback.format_exc()[-1500:]}
    print(f"{name:8s} {json.dumps(results['rows'][name])}", flush=True)
try:  # the same 30 steps of the same stream, eager and replayed
    (eager, eager_student), (graphed, graphed_student) = runner(EagerSteps), runner(GraphedSteps)
    for index in range(30):
        eager(1e-4 * (1 + index % 3))
        graphed(1e-4 * (1 + index % 3))
    flat = lambda model: torch.cat([p.detach().flatten() for p in model.parameters()])  # noqa: E731
    difference = {"max_weight_difference": float((flat(eager_student) - flat(graphed_student)).abs().max())}
except Exception:
    difference = {"error": traceback.format_exc()[-1500:]}
results["rows"]["graph vs eager, 30 steps"] = difference
print(json.dumps(difference), flush=True)
OUT.write_text(json.dumps(results, indent=1))
print(f"wrote {OUT}")
