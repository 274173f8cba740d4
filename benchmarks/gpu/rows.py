"""GPU rows of the Panda: raw accuracy, one target's latency, 1000 and 10,000 targets x 16 + refinement beside
pytorch_kinematics' PseudoInverseIK on the same GPU. `python benchmarks/gpu/rows.py CHECKPOINT cuda`; JSON to $OUT."""

# ruff: noqa: B023  (each lambda is timed at once, inside its loop turn)
import json
import math
import os
import statistics
import sys
import time
from pathlib import Path

import torch

import ikdp
from ikdp.cuda_graph import CapturedReverseDiffusion

device = sys.argv[2] if len(sys.argv) > 2 else "cuda"
solver = ikdp.load(sys.argv[1], device=device)
arm = solver.arm
model = solver.model
out_path = Path(os.environ.get("OUT", "/tmp")) / "gpu_rows.json"
sync = torch.cuda.synchronize if device == "cuda" else (lambda: None)


def timed(fn, repeats=7):
    fn()
    sync()
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        r = fn()
        sync()
        times.append(time.perf_counter() - t)
    return statistics.median(times), r


res = {
    "gpu": torch.cuda.get_device_name() if device == "cuda" else "cpu",
    "torch": torch.__version__,
    "checkpoint": sys.argv[1],
}


def save():
    out_path.write_text(json.dumps(res, indent=1))
    print(json.dumps(res), flush=True)


targets_all = arm.end_effector(arm.random_poses(10000, generator=torch.Generator().manual_seed(0))).to(device)
t1000 = targets_all[:1000]
out = solver.solve(t1000, num_samples=1, sampler="ddpm", generator=torch.Generator(device).manual_seed(1))
pe = out.position_error[:, 0].cpu() * 1000
re = torch.rad2deg(out.rotation_error[:, 0].cpu())
res["raw_ddpm_k1"] = dict(
    pos_median=float(pe.median()),
    pos_mean=float(pe.mean()),
    rot_median=float(re.median()),
    rot_mean=float(re.mean()),
    over_50mm=float((pe > 50).float().mean()),
    p90=float(pe.quantile(0.9)),
)
save()
one = targets_all[:1]
for sampler, steps in (("ddpm", None), ("dpmpp2m", 10)):
    key = f"{sampler}{steps or ''}"
    s, _ = timed(
        lambda: model.sample(
            one, num_samples=16, sampler=sampler, steps=steps, generator=torch.Generator(device).manual_seed(0)
        )
    )
    res[f"one_target_k16_eager_ms_{key}"] = s * 1000
    try:
        graphed = CapturedReverseDiffusion(model, batch=1, num_samples=16, sampler=sampler, steps=steps)
        s, _ = timed(lambda: graphed(one, seed=0))
        res[f"one_target_k16_graph_ms_{key}"] = s * 1000
        eager = model.sample(
            one,
            num_samples=16,
            sampler=sampler,
            steps=steps,
            generator=torch.Generator(device).manual_seed(0),
            return_trajectory=True,
        )
        rep = graphed(one, seed=0)
        res[f"graph_bit_identical_{key}"] = bool(torch.equal(rep.states, eager.states))
        res[f"graph_max_abs_diff_{key}"] = float((rep.states - eager.states).abs().max())
    except Exception as e:
        res[f"graph_error_{key}"] = repr(e)[:300]
    save()


def verdict(joints, targets):
    goals = targets[:, None].expand(-1, joints.shape[1], -1)
    valid = (arm.position_error(joints, goals) < 1e-3) & (arm.rotation_error(joints, goals) < math.radians(1))
    return dict(success=float(valid.any(1).float().mean()), valid_per_target=float(valid.sum(1).float().mean()))


for count in (1000, 10000):
    tg = targets_all[:count]
    for sampler, steps in (("dpmpp2m", 10), ("ddpm", None)):
        try:
            s, o = timed(
                lambda: solver.solve(
                    tg,
                    num_samples=16,
                    sampler=sampler,
                    steps=steps,
                    refine_steps=5,
                    generator=torch.Generator(device).manual_seed(2),
                ),
                repeats=3,
            )
            res[f"ikdp_{sampler}{steps or ''}_k16_refine5_{count}"] = dict(seconds=s, **verdict(o.angles, tg))
        except Exception as e:
            res[f"ikdp_error_{sampler}_{count}"] = repr(e)[:300]
        save()
    try:
        import pytorch_kinematics as pk

        chain = pk.build_serial_chain_from_urdf(
            Path(
                arm.chain_description().urdf_path if hasattr(arm.chain_description(), "urdf_path") else arm.urdf_path
            ).read_bytes(),
            arm.ee_link,
        ).to(device=device)
        limits = arm.joint_limits.to(device)
        retry = torch.rand(16, arm.num_joints, generator=torch.Generator().manual_seed(9)).to(device)
        retry = limits[:, 0] + retry * (limits[:, 1] - limits[:, 0])
        ik = pk.PseudoInverseIK(
            chain,
            retry_configs=retry,
            joint_limits=limits,
            max_iterations=30,
            pos_tolerance=1e-3,
            rot_tolerance=math.radians(1),
            early_stopping_any_converged=True,
        )
        goal = pk.Transform3d(pos=tg[:, :3], rot=tg[:, 3:], device=device)
        s, sol = timed(lambda: ik.solve(goal), repeats=3)
        res[f"pk_pseudoinverse_16_retries_{count}"] = dict(seconds=s, **verdict(sol.solutions.detach().float(), tg))
    except Exception as e:
        res[f"pk_error_{count}"] = repr(e)[:300]
    save()
