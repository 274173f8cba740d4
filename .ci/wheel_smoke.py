"""Smoke test of an installed IKDP wheel, run by .ci/run from a folder outside the repository.

    python wheel_smoke.py core   # the wheel without extras: load the shipped model by name, solve one target
    python wheel_smoke.py viz    # with the [viz] extra: start the viewer on its default model, fetch its page
    python wheel_smoke.py robot  # with [viz,robots]: the viewer on the shipped Panda, its meshes drawn, a first solve
    python wheel_smoke.py train  # with [train] alone: `ikdp-train` trains a small planar model and writes it
    python wheel_smoke.py eval   # with [train,eval]: `ikdp-evaluate --quick` writes RESULTS.md, results.json, figures

Each check prints one line; any failure exits non-zero with the reason.
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import re
import signal
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

REPOSITORY = Path(__file__).resolve().parent.parent


def check(condition: bool, message: str) -> None:
    if not condition:
        raise SystemExit(f"wheel smoke test failed: {message}")
    print(f"ok: {message}", flush=True)


def installed_not_cloned() -> None:
    import ikdp

    location = Path(ikdp.__file__).resolve()
    check(REPOSITORY not in location.parents, f"ikdp is imported from the installed wheel ({location.parent})")


def core() -> None:
    """The library alone: no viewer, no plotting, the shipped models inside the package."""
    for extra in ("viser", "matplotlib"):
        check(importlib.util.find_spec(extra) is None, f"{extra} is not installed (the wheel without extras)")
    installed_not_cloned()
    import torch

    import ikdp
    from ikdp.shipped import DEFAULT_MODEL, shipped_dir

    check(shipped_dir().parent == Path(ikdp.__file__).resolve().parent, f"shipped models in {shipped_dir()}")
    solver = ikdp.load(DEFAULT_MODEL)
    result = solver.solve([[1.5, 2.0]], num_samples=4, refine_steps=5, generator=torch.Generator().manual_seed(0))
    best = float(result.tip_error.min())
    check(best < 1e-2, f"ikdp.load({DEFAULT_MODEL!r}) solves one target (best tip error {best:.2e})")
    from ikdp.denoisers.film_compiled import load_kernel

    check(load_kernel() is not None, "the compiled FiLM step builds from the wheel's own C source")
    from ikdp import compiled_chain

    check(compiled_chain.load_kernel() is not None, "the compiled refinement builds from the wheel's own C source")
    wheel_version = importlib.metadata.version("ikdp")
    check(ikdp.__version__ == wheel_version, f"ikdp.__version__ {ikdp.__version__} is the wheel's version")


def viz(timeout: float = 180.0) -> None:
    """`python -m ikdp_viz` with no arguments: the default model, a URL printed, the page served over HTTP."""
    installed_not_cloned()
    viewer = subprocess.Popen(
        [sys.executable, "-m", "ikdp_viz"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )
    try:
        deadline = time.monotonic() + timeout
        url, seen = None, []
        while url is None and time.monotonic() < deadline:
            line = viewer.stdout.readline()
            if not line:  # the viewer exited before printing its address
                break
            seen.append(line.rstrip())
            match = re.search(r"open (http://\S+)", line)
            url = match.group(1) if match else None
        check(url is not None, f"the viewer printed its address ({' | '.join(seen[-5:])})")
        with urllib.request.urlopen(url, timeout=60) as response:
            page = response.read().decode("utf-8", errors="replace")
            status = response.status
        check(status == 200 and "<html" in page.lower(), f"GET {url} serves the viewer's page ({len(page)} bytes)")
    finally:
        viewer.send_signal(signal.SIGINT)  # what Ctrl-C sends: the viewer stops cleanly
        try:
            viewer.wait(timeout=30)
        except subprocess.TimeoutExpired:
            viewer.kill()
            viewer.wait()
    check(viewer.returncode in (0, 130, -signal.SIGINT), f"the viewer stopped on Ctrl-C (exit {viewer.returncode})")


def robot(timeout: float = 120.0) -> None:
    """The README's robot view (`python -m ikdp_viz --ckpt ikdp_panda`) with only [viz,robots] installed.

    In this process, so that the scene can be read: a dependency that no extra lists fails here
    (trimesh's hull once needed scipy, which only [test] brought, and the Panda drew nothing).
    """
    installed_not_cloned()
    import contextlib
    import io

    import viser

    import ikdp
    from ikdp_viz.app import VizApp

    scipy = "installed" if importlib.util.find_spec("scipy") else "not installed"
    with contextlib.redirect_stdout(io.StringIO()):
        server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)  # any free port
    app = VizApp(server, ikdp.load("ikdp_panda"))
    try:
        check(app.wait_until_still(timeout), "the Panda's first solve finished")
        writer, view = app.writer, app.writer.view  # the view: the robot's nodes (ikdp_viz/robot_view.py)
        check(writer.error is None and app.solved is not None, "the Panda's first solve is on screen, no error")
        check(
            view.nodes_shape is not None and len(view.ghosts) == len(view.robot_meshes) > 0,
            f"its {len(view.robot_meshes)} link meshes and their ghosts were drawn (scipy {scipy})",
        )
        url = f"http://127.0.0.1:{server.get_port()}"
        with urllib.request.urlopen(url, timeout=60) as response:
            check(response.status == 200, f"GET {url} serves the viewer's page")
    finally:
        app.close()
        server.stop()


def run_script(name: str, *arguments: str, timeout: float) -> Path:
    """One of the wheel's console scripts, from this venv, in a fresh folder that `{folder}` in `arguments` names;
    checked to exit 0 (its last line of stderr shown). Returns the folder."""
    import tempfile

    folder = Path(tempfile.mkdtemp())
    command = [str(Path(sys.executable).parent / name), *(argument.format(folder=folder) for argument in arguments)]
    done = subprocess.run(command, capture_output=True, text=True, cwd=folder, timeout=timeout)
    check(done.returncode == 0, f"{name} {' '.join(arguments)} exits 0 ({done.stderr.strip().splitlines()[-1:]})")
    return folder


def train() -> None:
    """`ikdp-train` with only [train] installed: a few steps of a 3-link model, its checkpoint loadable."""
    installed_not_cloned()
    import ikdp

    folder = run_script("ikdp-train", "--joints", "3", "--steps", "5", "--output", "{folder}/small.pt", timeout=600)
    check(ikdp.load(folder / "small.pt").arm.num_joints == 3, "its checkpoint loads with 3 joints")


def evaluate() -> None:
    """`ikdp-evaluate --quick` with [train,eval] (and not [viz]): every stage runs and writes its report."""
    installed_not_cloned()
    arguments = ("--quick", "--out-dir", "{folder}/docs", "--cache-dir", "{folder}/cache")
    folder = run_script("ikdp-evaluate", *arguments, timeout=1200)
    written = sorted(path.name for path in (folder / "docs").iterdir())
    check({"RESULTS.md", "results.json", "figures"} <= set(written), f"it wrote {written}")


if __name__ == "__main__":
    checks = {"core": core, "viz": viz, "robot": robot, "train": train, "eval": evaluate}
    if len(sys.argv) != 2 or sys.argv[1] not in checks:
        raise SystemExit(f"usage: python {Path(__file__).name} {{{'|'.join(checks)}}}")
    checks[sys.argv[1]]()
