"""What a wheel promises: every code package listed, shipped models found, and no viewer or plotting import."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from ikdp.shipped import DEFAULT_MODEL, list_shipped, shipped_checkpoint, shipped_dir

REPO = Path(__file__).resolve().parent.parent

# Run in a fresh interpreter: refuses the optional extras' modules outright, as a venv without them would.
BLOCK_EXTRAS = textwrap.dedent(
    """
    import importlib.abc, sys

    class RefuseExtras(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in {"viser", "matplotlib", "trimesh", "tensorboard"}:
                raise ModuleNotFoundError(f"No module named {name!r} (blocked by the test)")
            return None

    sys.meta_path.insert(0, RefuseExtras())
    """
)


def run_python(code: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, timeout=120, check=False
    )


def test_every_code_package_is_in_the_wheel():
    tomllib = pytest.importorskip("tomllib")  # the standard library from Python 3.11
    listed = set(tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    on_disk = {
        ".".join(init.parent.relative_to(REPO).parts)
        for top in ("ikdp", "ikdp_viz")
        for init in (REPO / top).rglob("__init__.py")
    }
    assert on_disk <= listed, f"add to [tool.setuptools] packages: {sorted(on_disk - listed)}"


def test_shipped_models_are_found_by_name():
    assert shipped_dir() == REPO / "checkpoints"  # a clone: the top-level folder, not a copy
    assert DEFAULT_MODEL in [path.stem for path in list_shipped()]
    assert shipped_checkpoint(DEFAULT_MODEL) == shipped_checkpoint(DEFAULT_MODEL + ".pt")
    with pytest.raises(ValueError, match=f"not a shipped model.*{DEFAULT_MODEL}"):
        shipped_checkpoint("no_such_model")


def test_importing_ikdp_pulls_in_neither_viewer_nor_plotting():
    result = run_python(
        "import sys, ikdp, ikdp.train, ikdp.shipped\n"
        "print(sorted(m for m in ('viser', 'matplotlib', 'trimesh', 'tensorboard') if m in sys.modules))"
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "[]"


def test_solving_works_without_the_extras():
    result = run_python(
        BLOCK_EXTRAS
        + textwrap.dedent(
            """
            import torch, ikdp
            from ikdp.shipped import DEFAULT_MODEL
            solver = ikdp.load(DEFAULT_MODEL)  # a shipped model, by name
            out = solver.solve([[1.5, 2.0]], num_samples=2, refine_steps=5, generator=torch.Generator().manual_seed(0))
            print(float(out.tip_error.max()))
            """
        )
    )
    assert result.returncode == 0, result.stderr
    assert float(result.stdout.strip()) < 1e-2  # a refined pose lands on a reachable target


@pytest.mark.parametrize(("module", "argv"), [("ikdp_viz.__main__", []), ("ikdp_viz.record", ["--output", "x.html"])])
def test_the_viewer_without_its_extra_says_what_to_install_in_one_line(module, argv):
    result = run_python(BLOCK_EXTRAS + f"from {module} import main, PROGRAM; print(PROGRAM, flush=True); main({argv})")
    assert result.returncode == 2 and "Traceback" not in result.stderr, result.stderr
    program = result.stdout.strip()
    wanted = f"{program}: error: the viewer needs viser, trimesh, matplotlib: pip install 'ikdp[viz]'"
    assert result.stderr.strip() == wanted


def test_the_viewer_checks_for_exactly_the_viz_extras_packages():
    tomllib = pytest.importorskip("tomllib")
    from ikdp_viz.models import VIEWER_MODULES

    extra = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["optional-dependencies"]["viz"]
    assert sorted(VIEWER_MODULES.values()) == sorted(requirement.split(">")[0] for requirement in extra)
