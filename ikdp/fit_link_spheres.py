"""`python -m ikdp.fit_link_spheres panda z1`: fit the named robots' sphere covers (ikdp/link_spheres.py) again into
the package's folder, after a change to a robot's URDF or to the fitting rule."""

from __future__ import annotations

import sys

from ikdp.link_spheres import SHIPPED_FOLDER, fit_sphere_cover, store
from ikdp.robots import load_robot, robot_names


def main(argv: list[str] | None = None) -> None:
    """`python -m ikdp.fit_link_spheres panda z1`: fit the named robots' covers again into the package's folder."""
    names = sys.argv[1:] if argv is None else argv
    if not names or any(name.startswith("-") for name in names):
        usage = "usage: python -m ikdp.fit_link_spheres ROBOT [ROBOT ...]"
        raise SystemExit(f"{usage}, robots: {', '.join(robot_names())}")
    for name in names:
        try:
            arm = load_robot(name)
            cover = fit_sphere_cover(arm)
        except ValueError as error:
            raise SystemExit(f"ikdp.fit_link_spheres: error: {error}") from None
        path = store(arm, cover, SHIPPED_FOLDER)
        posed = cover.posed()
        print(
            f"{name}: {len(posed)} spheres ({len(cover.chain)} on the chain, {len(posed) - len(cover.chain)} on "
            f"{len(cover.hanging)} hanging links), radii {min(posed.radii):.4f} to {max(posed.radii):.4f} m -> {path}"
        )


if __name__ == "__main__":
    main()
