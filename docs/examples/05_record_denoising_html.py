"""Record a denoising to one self-contained HTML file: play it, pause it, scrub it, offline, no server.

The page holds the viewer's drawing of every reverse-diffusion step from noise to the solution (viser's
static client, in one file); send it to anyone with a browser. The same as
`python -m ikdp_viz.record --output denoising.html` (needs `pip install "ikdp[viz]"`).

    python docs/examples/05_record_denoising_html.py --output denoising.html --target 1.5 2.0
    python docs/examples/05_record_denoising_html.py --ckpt ikdp_panda --target 0.4 0.1 0.5 180 0 0
"""

from __future__ import annotations

from pathlib import Path

import tyro

from ikdp_viz.record import main as record


def main(
    output: Path = Path("denoising.html"),
    ckpt: str = "ikdp_n4",
    target: tuple[float, ...] = (1.5, 2.0),
    samples: int = 16,
    seed: int = 0,
    seconds: float = 4.0,
) -> None:
    """Write `output`: `samples` poses of `ckpt` denoising toward `target` (planar: x y; a robot: x y z in metres,
    then roll pitch yaw in degrees), played over `seconds`."""
    argv = ["--ckpt", ckpt, "--output", str(output), "--samples", str(samples), "--seed", str(seed)]
    record([*argv, "--seconds", str(seconds), "--target", *(str(value) for value in target)])


if __name__ == "__main__":
    tyro.cli(main)
