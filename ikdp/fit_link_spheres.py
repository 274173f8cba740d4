"""`python -m ikdp.fit_link_spheres panda z1 ikdp_g1`: fit the sphere covers (ikdp/link_spheres.py) of named robots,
or of the chains of a shipped model's arm (a tree's one per end effector), into the package's folder, after a change
to a robot's URDF or to the fitting rule."""

from __future__ import annotations

import sys

import ikdp
from ikdp.link_spheres import SHIPPED_FOLDER, fit_sphere_cover, store
from ikdp.robots import load_robot, robot_names
from ikdp.shipped import list_shipped


def main(argv: list[str] | None = None) -> None:
    """`python -m ikdp.fit_link_spheres panda z1 ikdp_g1` (the module docstring)."""
    names = sys.argv[1:] if argv is None else argv
    if not names or any(name.startswith("-") for name in names):
        usage = "usage: python -m ikdp.fit_link_spheres NAME [NAME ...]"
        raise SystemExit(f"{usage}, robots: {', '.join(robot_names())}, or a shipped model's name")
    for name in names:
        try:
            shipped = name in {path.stem for path in list_shipped()}
            chains = ikdp.load(name).arm.chains if shipped else (load_robot(name),)
            for arm in chains:
                cover = fit_sphere_cover(arm)
                path = store(arm, cover, SHIPPED_FOLDER)
                posed = cover.posed()
                print(
                    f"{name} ({arm.ee_link}): {len(posed)} spheres ({len(cover.chain)} on the chain, "
                    f"{len(posed) - len(cover.chain)} on {len(cover.hanging)} hanging links), radii "
                    f"{min(posed.radii):.4f} to {max(posed.radii):.4f} m -> {path}"
                )
        except ValueError as error:
            raise SystemExit(f"ikdp.fit_link_spheres: error: {error}") from None


if __name__ == "__main__":
    main()
