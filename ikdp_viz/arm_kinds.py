"""What the viewer does differently per kind of arm, in one place: planar (x, y) targets or chain pose targets.

The session, the solve and the app ask `arm_kind(solver)` instead of testing the arm's
type: where the first target sits, how a point asked for is pulled into the workspace,
which drawable arrays a solve becomes, how the gizmo's pose reads as a target and how
the model is described. Drawing itself is the scene writer's (one class per kind, see
`chain_scene_writer.scene_writer_class`). No viser here.
"""

from __future__ import annotations

import numpy as np
import torch

from ikdp_viz import chain_readouts, chain_scene, readouts, scene


class PlanarKind:
    """The paper's planar N-link arm: targets (2,) in its plane, an annulus for workspace."""

    name = "planar"
    default_sampler = ("ddpm", 20)  # the paper's sampler; the steps apply if the user picks one that skips

    def initial_target(self, solver, target=None) -> np.ndarray:
        """(2,) `target` clamped into the solver's workspace; a point up and to the right when None."""
        inner, outer = solver.reach
        point = np.array(target if target is not None else (0.55 * outer, 0.3 * outer), dtype=np.float64)
        return scene.clamp_to_workspace(point, inner, outer)[0]

    def clamp(self, solver, point) -> tuple[np.ndarray, bool]:
        """The nearest workspace point to `point` (a gizmo position's z is ignored), and whether it moved."""
        return scene.clamp_to_workspace(point, *solver.reach)

    def gizmo_target(self, solver, gizmo) -> np.ndarray:
        """The target a dragged gizmo asks for: its (x, y)."""
        return np.asarray(gizmo.position, dtype=np.float64)[:2]

    def drawable(self, result, solver, target, partial=None) -> tuple[scene.SolveView, np.ndarray]:
        """A solve's view and its trail (S+1, K*N, 2, 3); `partial` is for pose models (a planar target is a point)."""
        view = scene.build_view(result, solver.lengths, target)
        return view, scene.trail_points(view.joints)

    def model_text(self, solver) -> str:
        return readouts.model_text(solver.num_links, solver.lengths, solver.timesteps, solver.metadata)


class ChainKind:
    """A robot from a URDF (ikdp.chain_arm.ChainArm): pose targets (7,) position m + wxyz, a reach ball."""

    name = "chain"
    # The paper's DDPM, as for the planar arm: for the shipped Panda (20 targets, K = 16) the samples' median
    # error is 9.8 mm / 3.0 deg against DPM-Solver++(2M)-10's 24.4 mm / 8.6 deg, for 210 ms a solve instead of
    # 12 (benchmarks/viz_robot_settings.py); the steps apply when the user picks a sampler that skips some.
    default_sampler = ("ddpm", 10)

    def initial_target(self, solver, target=None) -> np.ndarray:
        """(target_dim,) `target` pulled into reach; the hand at mid-limits (surely reachable) when None."""
        if target is None or np.asarray(target).size != solver.arm.target_dim:
            return chain_scene.initial_pose_target(solver.arm)[: solver.arm.target_dim]
        return self.clamp(solver, target)[0]

    def clamp(self, solver, point) -> tuple[np.ndarray, bool]:
        """A target (7,) (or (3,) for position targets) with its position pulled onto the reach ball, and
        whether it moved. A pose's quaternion comes back normalised with w >= 0."""
        size = solver.arm.target_dim
        point = np.asarray(point, dtype=np.float64).reshape(-1)
        if point.shape != (size,) or not np.isfinite(point).all():
            what = "x, y, z, w, qx, qy, qz" if size == 7 else "x, y, z"
            raise ValueError(f"point: expected {size} finite numbers ({what}), got {point.tolist()}")
        target = chain_scene.pose_target(point[:3], point[3:]) if size == 7 else point
        inside = solver.arm.clamp_to_workspace(torch.as_tensor(target)).numpy()
        return inside, not np.allclose(inside[:3], target[:3], rtol=0.0, atol=1e-12)

    def gizmo_target(self, solver, gizmo) -> np.ndarray:
        """The target a dragged 6-DoF gizmo asks for: position then wxyz (7,), or the position alone."""
        pose = np.concatenate((np.asarray(gizmo.position, np.float64), np.asarray(gizmo.wxyz, np.float64)))
        return pose[: solver.arm.target_dim]

    def drawable(self, result, solver, target, partial=None) -> tuple[chain_scene.ChainView, np.ndarray]:
        """A solve's view and its trail: the K hands' paths, (S+1, K, 2, 3). `partial`: the solve's partial
        target (ikdp.PositionOnly or FreeAxis), whose residual the errors then measure; None: the full pose."""
        view = chain_scene.build_chain_view(result, solver.arm, target, partial=partial)
        return view, chain_scene.hand_paths(view.points)

    def model_text(self, solver) -> str:
        return chain_readouts.chain_model_text(solver.arm, solver.timesteps, solver.metadata)


ARM_KINDS = {"planar": PlanarKind(), "chain": ChainKind()}


def arm_kind(solver) -> PlanarKind | ChainKind:
    """The viewer's handling of `solver.arm` (by its `kind`: "planar" or "chain")."""
    kind = getattr(solver.arm, "kind", "planar")
    if kind not in ARM_KINDS:
        raise ValueError(f"solver: the viewer draws arms of kind {tuple(ARM_KINDS)}, got {kind!r}")
    return ARM_KINDS[kind]
