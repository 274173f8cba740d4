"""What the viewer's two commands share: finding a checkpoint, loading it, one-line errors (exit status 2).

`python -m ikdp_viz` (__main__.py) and `python -m ikdp_viz.record` (record.py) both import
this; neither imports the other.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

from ikdp.shipped import list_shipped, shipped_checkpoint


def fail(program: str, message: str) -> None:
    """One line on stderr, `<program>: error: <message>`, and exit status 2: no traceback reaches a user."""
    print(f"{program}: error: {message}", file=sys.stderr)
    raise SystemExit(2)


# What the [viz] extra installs, module -> package (tests/test_packaging.py holds them to pyproject.toml)
VIEWER_MODULES = {module: module for module in ("viser", "trimesh", "matplotlib", "imageio")} | {"collada": "pycollada"}


def installed(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):  # a finder that refuses it, or a module set to None: not usable either
        return False


def check_viewer_packages(program: str) -> None:
    """Exit 2 with one line naming what the [viz] extra would have installed (a core install lacks it)."""
    missing = [package for module, package in VIEWER_MODULES.items() if not installed(module)]
    if missing:
        fail(program, f"the viewer needs {', '.join(missing)}: pip install 'ikdp[viz]'")


def checkpoint_path(ckpt: str) -> Path:
    """A shipped model's file when `ckpt` names one and is no file here, else `ckpt` as a path."""
    if not Path(ckpt).exists() and Path(ckpt).stem in {path.stem for path in list_shipped()} and "/" not in ckpt:
        return shipped_checkpoint(ckpt)
    return Path(ckpt)


def load_solver(program: str, path: Path, device: str = "cpu"):
    """`ikdp.load(path, device)`, or exit 2 with one line saying why the checkpoint or the device cannot be used."""
    import ikdp  # imported here: torch is slow to import and `--help` needs none of it

    try:
        return ikdp.load(path, device=device)
    except ikdp.CheckpointError as error:
        fail(program, str(error))
    except OSError as error:
        fail(program, f"{path}: cannot read it ({error.strerror or error})")
    except ValueError as error:  # ikdp.load's answer to an unknown or absent device: "device: ..."
        fail(program, f"--device {device}: {str(error).removeprefix('device: ')}")
    except (RuntimeError, AssertionError) as error:  # torch's, should the device fail later
        reason = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
        fail(program, f"--device {device}: {reason}")


def command_target(solver, numbers):
    """The target `--target NUMBERS` asks for; ValueError when the numbers do not make one for this arm."""
    from ikdp_viz.session import initial_target
    from ikdp_viz.typed_target import target_from_numbers

    arm = solver.arm
    return target_from_numbers(
        numbers, kind=getattr(arm, "kind", "planar"), target_dim=getattr(arm, "target_dim", 2),
        current=initial_target(solver),
    )  # fmt: skip


def target_flag_error(numbers, error: ValueError) -> str:
    return f"--target {' '.join(f'{value:g}' for value in numbers)}: {error}"
