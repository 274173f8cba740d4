"""GPU (a lent H200): three Panda trainings side by side through `python -m ikdp.train --device cuda`, each measured.

    python benchmarks/gpu/train_ablation.py 390     # the seconds each training may take; files under $OUT

Run from the repository root with the Panda URDF copied to .carry/example-robot-data/robots/panda_description/urdf/
(the device machine has no example-robot-data). A 200-step probe sets each run's --steps to fill the budget; each
final checkpoint is measured (raw DDPM, K = 1, robot_benchmark's 1000 targets) and written without its optimizer
state, split in 15 MB parts. The runs (epsilon- against x0-prediction, MLP against FiLM) are in `runs` below; their
numbers are in benchmarks/results/gpu_panda_ablation.json, and what they chose (the GPU recipe) in docs/robots.md.
"""

# ruff: noqa: E402  (a script run once on the device machine: the imports follow its steps)
import json
import os
import subprocess
import sys
import time
from pathlib import Path

OUT = Path(os.environ["OUT"])
budget = float(sys.argv[1]) if len(sys.argv) > 1 else 430
URDF = str(Path(".carry/example-robot-data/robots/panda_description/urdf/panda.urdf").resolve())
common = [
    "--urdf",
    URDF,
    "--ee-link",
    "panda_hand",
    "--timesteps",
    "100",
    "--hidden",
    "512",
    "--ema",
    "0.999",
    "--batch",
    "8192",
    "--warmup",
    "300",
    "--device",
    "cuda",
    "--lr",
    "1e-3",
]
recipe = ["--prediction", "epsilon", "--schedule", "cosine", "--tip-loss-weight", "0", "--snr-gamma", "0"]
runs = {
    "X1_mlp_eps": ["--denoiser", "mlp", "--blocks", "6", *recipe],
    "X2_film_eps": ["--denoiser", "film", "--blocks", "4", *recipe],
    "X3_mlp_x0": ["--denoiser", "mlp", "--blocks", "6", "--schedule", "karras"],
}
Path("runs").mkdir(exist_ok=True)


def launch(name, extra, steps, evals, save_every):
    cmd = [
        sys.executable,
        "-m",
        "ikdp.train",
        *common,
        *extra,
        "--steps",
        str(steps),
        "--eval-targets",
        str(evals),
        "--save-every",
        str(save_every),
        "--output",
        f"runs/{name}.pt",
        "--log-dir",
        f"runs/logs/{name}",
    ]
    return subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=open(f"runs/{name}.log", "w")), cmd


import re

t0 = time.time()
probes = [launch("probe_" + n, e, 200, 0, 10**6)[0] for n, e in runs.items()]
[p.wait() for p in probes]
probe = time.time() - t0
rates = {n: float(re.findall(r"([0-9.]+)it/s", open(f"runs/probe_{n}.log").read())[-1]) for n in runs}
startup = max(5.0, probe - 200 / min(rates.values()))
steps = {n: int((budget - startup - 15) * r) for n, r in rates.items()}
print(
    f"probe: 200 steps in {probe:.1f}s, rates {rates} it/s x3 concurrent, startup {startup:.1f}s -> {steps}", flush=True
)
started = time.time()
procs = {n: launch(n, e, steps[n], 500, max(500, steps[n] // 4)) for n, e in runs.items()}
for n, (p, cmd) in procs.items():
    p.wait()
    print(n, "exit", p.returncode, f"{time.time() - started:.0f}s", " ".join(cmd[2:]), flush=True)
    print(open(f"runs/{n}.log").read()[-400:], flush=True)
import torch

import ikdp
from ikdp.checkpoint import read_checkpoint, save_checkpoint

results = {"steps": steps, "rates_3_concurrent": rates, "gpu": torch.cuda.get_device_name()}
for n in runs:
    path = Path(f"runs/{n}.pt")
    if not path.exists():
        continue
    solver = ikdp.load(path, device="cuda")
    arm = solver.arm
    targets = arm.end_effector(arm.random_poses(1000, generator=torch.Generator().manual_seed(0)))
    out = solver.solve(targets.cuda(), num_samples=1, sampler="ddpm", generator=torch.Generator("cuda").manual_seed(1))
    pe = out.position_error.cpu()[:, 0] * 1000
    re = torch.rad2deg(out.rotation_error.cpu()[:, 0])
    row = {
        "pos_median_mm": float(pe.median()),
        "pos_mean_mm": float(pe.mean()),
        "rot_median_deg": float(re.median()),
        "rot_mean_deg": float(re.mean()),
        "over_50mm": float((pe > 50).float().mean()),
        "train_seconds": read_checkpoint(path)["train"]["seconds"],
    }
    results[n] = row
    print(n, row, flush=True)
    payload = read_checkpoint(path)
    slim = {k: payload[k] for k in ("format", "version", "model", "prior", "train", "metrics", "state_dict")}
    save_checkpoint(Path(f"runs/{n}_slim.pt"), slim)
    subprocess.run(["split", "-b", "15M", "-d", f"runs/{n}_slim.pt", str(OUT / f"{n}.pt.part")])
(OUT / "gpu_results.json").write_text(json.dumps(results, indent=1))
subprocess.run(["tar", "czf", str(OUT / "logs.tgz"), "runs/logs"] + [f"runs/{n}.log" for n in runs])
