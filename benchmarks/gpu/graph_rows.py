"""GPU: one target, K = 16, the eager loop against its CUDA-graph replay (ikdp/cuda_graph.py), and whether the two
give bit-identical states. `python benchmarks/gpu/graph_rows.py`; JSON to $OUT (docs/library.md, "Capture on a GPU")."""

# ruff: noqa: B023  (each lambda is timed at once, inside its loop turn)
import json
import os
import statistics
import time
import traceback

import torch

import ikdp
from ikdp.cuda_graph import CapturedReverseDiffusion

res = {}
for name in ("ikdp_panda", "ikdp_n4"):
    solver = ikdp.load(name, device="cuda")
    model = solver.model
    one = solver.arm.end_effector(solver.arm.random_poses(1, generator=torch.Generator().manual_seed(0))).cuda()
    for sampler, steps in (("ddpm", None), ("dpmpp2m", 10)):
        key = f"{os.path.basename(name)}_{sampler}{steps or ''}"

        def timed(fn, n=15):
            fn()
            torch.cuda.synchronize()
            ts = []
            for _ in range(n):
                t = time.perf_counter()
                fn()
                torch.cuda.synchronize()
                ts.append(time.perf_counter() - t)
            return statistics.median(ts) * 1000

        try:
            res[key + "_eager_ms"] = timed(
                lambda: model.sample(
                    one, num_samples=16, sampler=sampler, steps=steps, generator=torch.Generator("cuda").manual_seed(0)
                )
            )
            g = CapturedReverseDiffusion(model, batch=1, num_samples=16, sampler=sampler, steps=steps)
            res[key + "_graph_ms"] = timed(lambda: g(one, seed=0))
            e = model.sample(
                one,
                num_samples=16,
                sampler=sampler,
                steps=steps,
                generator=torch.Generator("cuda").manual_seed(0),
                return_trajectory=True,
            )
            r = g(one, seed=0)
            res[key + "_bit_identical"] = bool(torch.equal(r.states, e.states))
        except Exception:
            res[key + "_error"] = traceback.format_exc()[:1200]
        print(json.dumps(res), flush=True)
open(os.environ["OUT"] + "/graph_rows.json", "w").write(json.dumps(res, indent=1))
