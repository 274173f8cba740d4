"""The figures, drawn from the results dict alone (so results.json can redraw them).

matplotlib with the Agg backend; every function writes one PNG and returns its path.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402

from ikdp.kinematics import forward_kinematics  # noqa: E402


def _arm(axis, headings, lengths, **style):
    joints = forward_kinematics(
        torch.as_tensor(headings, dtype=torch.float64), torch.as_tensor(lengths, dtype=torch.float64)
    )
    axis.plot(joints[:, 0], joints[:, 1], **style)


def _frame(axis, reach: float, title: str):
    axis.set_xlim(-reach * 1.05, reach * 1.05)
    axis.set_ylim(-reach * 1.05, reach * 1.05)
    axis.set_aspect("equal")
    axis.add_patch(plt.Circle((0, 0), reach, fill=False, color="0.85", lw=0.8))
    axis.set_title(title, fontsize=9)
    axis.tick_params(labelsize=7)


def _save(figure, path: Path, *, dpi: int = 120, tight: bool = True) -> Path:
    """Write one figure to `path` and free it (pyplot keeps every open figure alive)."""
    if tight:
        figure.tight_layout()
    figure.savefig(path, dpi=dpi)
    plt.close(figure)
    return path


def reverse_process(results: dict, path: Path) -> Path:
    """Paper Fig. "vis": every state of the reverse process of one target, faint (noise) to dark (final)."""
    panels = results["reverse_process"]
    figure, axes = plt.subplots(1, len(panels), figsize=(4 * len(panels), 4.2))
    axes = np.atleast_1d(axes)
    for axis, (joints, panel) in zip(axes, panels.items(), strict=False):
        trajectory = panel["trajectory"]
        colours = plt.cm.Blues(np.linspace(0.15, 1.0, len(trajectory)))
        for index, (state, colour) in enumerate(zip(trajectory, colours, strict=False)):
            _arm(
                axis,
                state,
                panel["lengths"],
                color=colour,
                lw=0.6 + 1.6 * index / len(trajectory),
                alpha=0.25 + 0.75 * index / len(trajectory),
            )
        _arm(axis, trajectory[-1], panel["lengths"], color="navy", lw=2.2, marker="o", ms=3)
        axis.plot(*panel["target"], "x", color="red", ms=11, mew=2.5)
        _frame(
            axis,
            sum(panel["lengths"]),
            f"N={joints}: {len(trajectory) - 1} DDPM steps, final miss {panel['final_tip_error']:.3g}",
        )
    figure.suptitle(
        "Reverse diffusion of one target (faint: noisy states, dark: final pose; red x: target)", fontsize=10
    )
    return _save(figure, path)


def forward_noising(results: dict, path: Path) -> Path:
    """Paper Fig. "gaussian": arccos(t_x / N) and the first diffused coordinate, at several diffusion times."""
    data = results["forward_noising"]
    times = data["times"]
    figure, axes = plt.subplots(2, len(times), figsize=(3 * len(times), 5.2), squeeze=False)
    bins = np.array(data["bins"])
    coordinate_bins = np.linspace(-4, 4, 41)
    for column, (t, entry) in enumerate(times.items()):
        counts = np.array(entry["arccos_counts"])
        axes[0, column].bar(
            bins[:-1], counts / counts.sum() / np.diff(bins), width=np.diff(bins), align="edge", color="tab:blue"
        )
        axes[0, column].set_title(f"t = {t}  (alpha_bar = {entry['alpha_cumprod']:.2f})", fontsize=9)
        axes[0, column].set_xlabel("arccos(t_x / N)", fontsize=8)
        counts = np.array(entry["first_coordinate_counts"])
        axes[1, column].bar(
            coordinate_bins[:-1],
            counts / counts.sum() / np.diff(coordinate_bins),
            width=np.diff(coordinate_bins),
            align="edge",
            color="tab:orange",
        )
        grid = np.linspace(-4, 4, 200)
        axes[1, column].plot(grid, np.exp(-(grid**2) / 2) / np.sqrt(2 * np.pi), "k--", lw=1)
        axes[1, column].set_xlabel("first diffused coordinate theta^0 / pi", fontsize=8)
        for axis in axes[:, column]:
            axis.tick_params(labelsize=7)
    figure.suptitle(
        f"Forward diffusion of poses from the uniform prior, N={data['num_links']}, T={data['timesteps']} "
        "(dashed: N(0, 1))",
        fontsize=10,
    )
    return _save(figure, path)


def training_curves(results: dict, path: Path) -> Path:
    """Paper Fig. "train_loss": the loss on theta and the tip distance of the prediction, per checkpoint."""
    curves = results["training_curves"]
    figure, axes = plt.subplots(1, 3, figsize=(14, 4))
    tags = [
        ("train/theta_loss", "loss on theta (MSE on the diffused vector)"),
        ("train/tip_distance", "tip distance of the prediction"),
        ("eval/tip_error_median", "median tip error, DDPM K=1 (at saves)"),
    ]
    for axis, (tag, title) in zip(axes, tags, strict=False):
        for stem, scalars in curves.items():
            if scalars.get(tag):
                steps, values = zip(*scalars[tag], strict=False)
                axis.plot(steps, values, label=stem, lw=1, marker="o" if tag.startswith("eval") else None, ms=3)
        axis.set_yscale("log")
        axis.set_xlabel("step")
        axis.set_title(title, fontsize=9)
        axis.grid(alpha=0.3)
    if curves:
        axes[0].legend(fontsize=7)
    else:
        axes[0].text(0.5, 0.5, "no TensorBoard logs found", ha="center", transform=axes[0].transAxes)
    return _save(figure, path)


def tip_error_cdf(results: dict, path: Path) -> Path:
    """Distribution of the tip error of one solution per target, per method, each arm (FK-of-uniform targets)."""
    arms = results["arms"]
    figure, axes = plt.subplots(1, len(arms), figsize=(5.5 * len(arms), 4.5), squeeze=False)
    for axis, (joints, arm) in zip(axes[0], arms.items(), strict=False):
        for index, (name, entry) in enumerate(arm["methods"].items()):
            quantiles = np.maximum(np.array(entry["fk_uniform"]["tip_error_quantiles"]), 1e-9)
            style = "-" if entry["family"] == "ikdp" else "--" if entry["family"] == "learned" else ":"
            axis.plot(
                quantiles, np.linspace(0, 1, len(quantiles)), style, label=name, lw=1.3, color=plt.cm.tab20(index % 20)
            )
        for fraction in (1e-3, 1e-2):
            axis.axvline(fraction * arm["reach"], color="0.6", lw=0.8)
        axis.set_xscale("log")
        axis.set_xlim(1e-8, 2 * arm["reach"])
        axis.set_xlabel("tip error (bone lengths); grey: 1e-3 and 1e-2 of reach")
        axis.set_ylabel("share of targets")
        axis.set_title(f"N={joints}, K=1 per target", fontsize=10)
        axis.grid(alpha=0.3)
    axes[0, -1].legend(fontsize=6, loc="upper left")
    return _save(figure, path)


def solution_fans(results: dict, path: Path) -> Path:
    """K solutions of a few targets per method, drawn over each other, so diversity shows."""
    fans = results["fans"]
    names = list(fans.get("headings", {}))
    targets = fans.get("targets", [])
    if not names:
        figure = plt.figure()
        figure.text(0.5, 0.5, "no N=4 fans in this run", ha="center")
        return _save(figure, path, tight=False)
    lengths = [1.0] * fans["num_links"]
    figure, axes = plt.subplots(len(targets), len(names), figsize=(2.1 * len(names), 2.2 * len(targets)), squeeze=False)
    for column, name in enumerate(names):
        for row, target in enumerate(targets):
            axis = axes[row, column]
            for pose in fans["headings"][name][row]:
                _arm(axis, pose, lengths, color="tab:blue", lw=0.7, alpha=0.35)
            axis.plot(*target, "x", color="red", ms=8, mew=2)
            _frame(axis, sum(lengths), name if row == 0 else "")
            axis.set_xticks([])
            axis.set_yticks([])
        axes[0, column].title.set_fontsize(6)
    figure.suptitle("K solutions per target (red x), N=4: all samples drawn, valid or not", fontsize=10)
    return _save(figure, path, dpi=110)


def draw_all(results: dict, folder: Path) -> dict[str, str]:
    folder.mkdir(parents=True, exist_ok=True)
    drawn = {}
    for name, function in [
        ("reverse_process", reverse_process),
        ("forward_noising", forward_noising),
        ("training_curves", training_curves),
        ("tip_error_cdf", tip_error_cdf),
        ("solution_fans", solution_fans),
    ]:
        drawn[name] = str(function(results, folder / f"{name}.png"))
    return drawn
