"""The defaults a training takes from its arm: what the command line leaves out comes from a recipe.

A planar arm keeps the recipe its models were trained with. A robot (`--robot`, `--urdf`) takes the robot
recipe for the device: on a GPU the Panda's (ε-prediction, cosine schedule, plain MSE, width 512, batch 8192:
docs/robots.md, "What did not work"); on a CPU a smaller network and batch with x0-prediction, the karras schedule and
the FK-consistency term, which land near a solution within the first thousand steps, where ε-prediction
needs the GPU's large batches (on the xArm7, 100 against 307 mm
after 1,500 steps of one CPU thread). A tree (several end effectors, `--ee-link` twice or more) on a CPU takes the
CPU recipe with half the batch and a shorter weight average: its step costs more than a chain's, so a budget of
minutes gives it fewer steps, and the 0.999 average still held a large share of the early weights at its end.
Every value the run used, given or taken from a recipe, is written into the checkpoint.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace


@dataclass(frozen=True)
class Recipe:
    """Training values that depend on the arm and the device; each field is also a TrainConfig option."""

    name: str  # how --help and the checkpoint name it
    timesteps: int  # diffusion steps T
    schedule: str  # noise schedule
    prediction: str  # sample (x_0) or epsilon
    hidden: int  # denoiser width
    blocks: int  # residual blocks
    ema: float  # weight averaging decay (0: none)
    tip_loss_weight: float  # FK-consistency term
    snr_gamma: float  # Min-SNR weighting (0: uniform over t)
    steps: int  # optimizer steps when no --minutes is given
    batch: int  # poses per step
    lr: float  # peak learning rate
    warmup: int  # warm-up steps
    dls_skip: bool  # robots (chain_film): the DLS step reaches the estimate through a learned gain
    limit_aware_step: bool  # robots (chain_film): the DLS step solved without the joints a limit holds


PLANAR = Recipe(
    name="planar",
    timesteps=80,
    schedule="linear",
    prediction="sample",
    hidden=128,
    blocks=3,
    ema=0.0,
    tip_loss_weight=100.0,
    snr_gamma=5.0,
    steps=20_000,
    batch=1024,
    lr=1e-3,
    warmup=500,
    dls_skip=False,
    limit_aware_step=False,
)
ROBOT_GPU = Recipe(
    name="robot, GPU",
    timesteps=100,
    schedule="cosine",
    prediction="epsilon",
    hidden=512,
    blocks=4,
    ema=0.999,
    tip_loss_weight=0.0,
    snr_gamma=0.0,
    steps=12_000,
    batch=8192,
    lr=1e-3,
    warmup=300,
    dls_skip=False,
    limit_aware_step=False,
)
ROBOT_CPU = Recipe(
    name="robot, CPU",
    timesteps=100,
    schedule="karras",
    prediction="sample",
    hidden=256,
    blocks=4,
    ema=0.999,
    tip_loss_weight=100.0,
    snr_gamma=5.0,
    steps=20_000,
    batch=1024,
    lr=1e-3,
    warmup=500,
    dls_skip=True,
    limit_aware_step=True,
)

# The G1's two hands, raw K = 1 median of the worse hand on the same 500 held-out targets, one CPU thread: after 8
# minutes side by side on the same loaded cores, 45.7 mm (3,502 steps) against 54.0 mm (2,225) for the chain's batch
# 1,024 / EMA 0.999; after 3, batch 512 / 0.999 75 mm beside 78 for the chain's, and 0.995 59 mm (0.99: 64 mm)
TREE_CPU = replace(ROBOT_CPU, name="tree, CPU", batch=512, ema=0.995)

RECIPE_FIELDS = tuple(field.name for field in fields(Recipe) if field.name != "name")
ARM_KINDS = ("planar", "chain", "tree")  # a planar arm, a robot's serial chain, a robot's tree of end effectors
RECIPES = {  # (arm kind, device: cuda or cpu) -> recipe
    ("planar", "cpu"): PLANAR,
    ("planar", "cuda"): PLANAR,
    ("chain", "cpu"): ROBOT_CPU,
    ("chain", "cuda"): ROBOT_GPU,
    ("tree", "cpu"): TREE_CPU,
    ("tree", "cuda"): ROBOT_GPU,
}


def recipe_for(*, arm: str, device_type: str) -> Recipe:
    """The recipe of an arm kind (ARM_KINDS) on a device ("cuda", or anything else: a CPU)."""
    if arm not in ARM_KINDS:
        raise ValueError(f"arm: got {arm!r}, expected one of {', '.join(ARM_KINDS)}")
    return RECIPES[arm, "cuda" if device_type == "cuda" else "cpu"]


def recipes_help() -> str:
    """A table of the recipes for --help: one line per option, its value per recipe."""
    recipes = (PLANAR, ROBOT_CPU, TREE_CPU, ROBOT_GPU)
    lines = ["Options left out (None) take the arm's recipe: " + " | ".join(recipe.name for recipe in recipes)]
    width = max(len(name) for name in RECIPE_FIELDS)
    for name in RECIPE_FIELDS:
        values = " | ".join(shown(getattr(recipe, name)) for recipe in recipes)
        lines.append(f"  {name.replace('_', '-'):<{width}}  {values}")
    return "\n".join(lines)


def shown(value) -> str:
    if isinstance(value, bool):
        return "yes" if value else "no"
    return value if isinstance(value, str) else f"{value:g}"
