"""Robot-description files of the `example-robot-data` wheel, found through its installed file list.

A checkpoint records the absolute URDF path it was trained on, e.g.
`/home/me/venv/.../example-robot-data/robots/panda_description/urdf/panda.urdf`; on another
machine or in another environment that path is gone, but the same file is installed under
another prefix. `installed_copy` finds it there, so the viewer can still draw the robot's meshes.
"""

from __future__ import annotations

from importlib import metadata
from pathlib import Path

EXAMPLE_ROBOT_DATA = "example-robot-data"  # the distribution that ships the URDFs and meshes
ROBOTS_FOLDER = "example-robot-data/robots/"  # where its robot folders lie, under any install prefix


def example_robot_data_file(relative: str) -> Path:
    """A file under example-robot-data's `robots/` folder, located through the installed distribution."""
    try:
        distribution = metadata.distribution(EXAMPLE_ROBOT_DATA)
    except metadata.PackageNotFoundError:
        raise ValueError(f"robot: the URDFs need `pip install {EXAMPLE_ROBOT_DATA}`, which is not installed") from None
    suffix = f"robots/{relative}"
    for file in distribution.files or ():
        if file.as_posix().endswith(suffix):
            return Path(distribution.locate_file(file)).resolve()
    raise ValueError(f"robot: {EXAMPLE_ROBOT_DATA} has no file ending in {suffix!r}")


def installed_copy(recorded: str | Path) -> Path | None:
    """The file of example-robot-data that `recorded` names, as installed in this environment; else `recorded`
    itself if it exists; else None.

    This environment's install comes first: a recorded path that happens to exist here may be a stale copy
    (another venv, or a bare URDF copied beside a training run) without the meshes the viewer draws.
    """
    path = Path(recorded)
    text = path.as_posix()
    if ROBOTS_FOLDER in text:
        try:
            return example_robot_data_file(text.rsplit(ROBOTS_FOLDER, 1)[1])
        except ValueError:  # not installed, or a file this version does not ship
            pass
    return path if path.is_file() else None
