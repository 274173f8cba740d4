"""The planar arm's kind: its maths, texts, colours and legend for the viewer; its nodes are planar_view.py's.

No viser here. `arm_kinds.arm_kind(solver)` picks this or chain_kind.py: the only place that
branches on the kind of arm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ikdp_viz import planar_scene, readouts
from ikdp_viz.constraint_scene import sample_tints
from ikdp_viz.planar_scene import emphasis_colors, fade_colors, follows_one
from ikdp_viz.readouts import model_words
from ikdp_viz.student import student_sampling
from ikdp_viz.style import (
    ACCENT_DARK,
    ACCENT_FAINT,
    DARK,
    ESTIMATE,
    FAINT,
    HOLDS,
    HOLDS_OTHERS,
    JOINT_SPACE_DOT,
    OBSTACLE,
    OTHERS_FINAL,
    PRIOR,
    REFINED,
    TARGET_RED,
    TIP_DARK,
    TIP_FAINT,
    TRAIL_FAINT,
    VIOLATES,
    VIOLATES_OTHERS,
    Entry,
    Swatch,
)

PLAYING_TRAIL_STATES = 6  # the trail while an animation plays: every s-th state; all once it stops
PLAYING_FOLLOWED_STATES = 12  # the same for the one sample followed (the default picture)


@dataclass(frozen=True)
class PlanarPalette:
    """The colours of one planar solve with one sample highlighted, every state at once."""

    arms: np.ndarray  # (S+1, K, 3) uint8 each arm's colour at each state
    trail: np.ndarray  # (S+1, K*N, 2, 3) uint8 each trail segment's colour
    tips: np.ndarray  # (S+1, 3) uint8 the tips' colour at each state
    dots: np.ndarray  # (K, 3) uint8 the joint-space dots: dark at every state, the highlighted one blue
    compare_arms: np.ndarray | None = None  # (S'+1, K, 3) uint8 the compared sampler's arms (None: no comparison)
    compare_trail: np.ndarray | None = None  # (S'+1, K*N, 2, 3) uint8 its trail segments' colours


class PlanarKind:
    """The paper's planar N-link arm: targets (2,) in its plane, an annulus for workspace."""

    name = "planar"
    default_sampler = ("ddpm", 20)  # the paper's sampler; the steps apply if the user picks one that skips
    opens_on_student = False  # the paper's figure first; a planar DDPM solve takes milliseconds anyway
    opens_with_trail = True  # the paper's figure: the trail from noise to the pose
    chart_error, chart_unit, chart_scale = "tip error", "bone lengths", 1.0  # the chart's y: view.tip_error * scale
    holds_text = "constraints hold at the step shown (the others lighter)"
    partial_target_note = None  # a point target: nothing to leave free, nothing to say
    flat = True  # drawn in its plane: obstacles are discs, their gizmos move in the plane
    pose_targets = False  # a target is a point: nothing of it to leave free
    teaches = True  # the tour and "noise it" are written about this arm
    previews_drags = False  # a planar solve is fast enough to draw at every drag event
    draws_joint_space = True  # the joint-space square: two headings of this arm

    @staticmethod
    def target_from_numbers(values, solver, current) -> np.ndarray:
        """The typed numbers as a target, not yet pulled into the workspace (typed_target.py)."""
        from ikdp_viz.typed_target import point_from_numbers  # here: the kinds import no viser

        return point_from_numbers(values)

    @staticmethod
    def lock_fields(arm) -> list:
        from ikdp_viz.typed_target import heading_lock_fields

        return heading_lock_fields(arm)

    @staticmethod
    def obstacle_radius(arm) -> float:
        return round(0.1 * arm.span, 3)

    @staticmethod
    def sample_path(view, sample: int) -> tuple[np.ndarray, tuple[int, ...]]:
        """(S, N+1, 3) one sample's joints at every state, lifted just above the grid and under the arms of the step
        shown: the constraint overlay's polyline (one: no point counts)."""
        points = view.joints[:, sample]
        points = np.concatenate([points, np.full((*points.shape[:-1], 1), 0.001 * float(np.sum(view.lengths)))], -1)
        return points, ()

    violates_text = "constraints fail at the step shown"

    def configure_panel(self, panel) -> None:
        """Every control applies to a planar arm as the panel builds it."""

    def initial_target(self, solver, target=None) -> np.ndarray:
        """(2,) `target` clamped into the solver's workspace; a point up and to the right when None."""
        inner, outer = solver.reach
        point = np.array(target if target is not None else (0.55 * outer, 0.3 * outer), dtype=np.float64)
        return planar_scene.clamp_to_workspace(point, inner, outer)[0]

    def clamp(self, solver, point) -> tuple[np.ndarray, bool]:
        """The nearest workspace point to `point` (a gizmo position's z is ignored), and whether it moved."""
        return planar_scene.clamp_to_workspace(point, *solver.reach)

    def gizmo_target(self, solver, gizmo, current) -> np.ndarray:
        """The target a dragged gizmo asks for: its (x, y) (the one gizmo: nothing of `current` is kept)."""
        return np.asarray(gizmo.position, dtype=np.float64)[:2]

    def drawable(self, result, solver, target, partial=None) -> tuple[planar_scene.SolveView, np.ndarray]:
        """A solve's view and its trail (S+1, K*N, 2, 3); `partial` is for pose models (a planar target is a point)."""
        view = planar_scene.build_view(result, solver.lengths, target)
        return view, planar_scene.trail_points(view.joints)

    def model_text(self, solver) -> str:
        student_steps = None if solver.student is None else student_sampling(solver.student)[1]
        return model_words(solver.num_links, solver.lengths, solver.timesteps, solver.metadata, student_steps)

    def target_text(self, solver, target: np.ndarray, clamped: bool) -> str:
        return readouts.target_text(target, clamped, solver.reach)

    def target_words(self, target: np.ndarray, arm=None) -> str:
        """The target in a recording's label."""
        return f"target x = {target[0]:+.3f}, y = {target[1]:+.3f}"

    def typed_numbers(self, inputs, arm) -> tuple[float, ...]:
        """The numbers typed in the panel's Target folder."""
        return tuple(inputs.xy.value)

    def write_typed_fields(self, inputs, target: np.ndarray) -> None:
        """The typed-target fields show the target solved (so a small change is one edit away)."""
        inputs.show_fields(point=True, rotation=False)
        inputs.xy.value = tuple(round(float(value), 3) for value in target[:2])

    def flat_picture(self, solved) -> tuple[np.ndarray, np.ndarray, float | None, np.ndarray]:
        """What the exported files draw: (polylines (S+1, K, N+1, 2), target (2,), workspace radius, arm colours
        chosen from a palette by `arm_colors`): the plane itself."""
        view = solved.view
        return view.joints, view.target, float(np.sum(view.lengths)), None

    def arm_colors(self, palette) -> np.ndarray:
        """(S+1, K, 3) each sample's line colour at each state, from this kind's palette."""
        return palette.arms

    def light_trail_states(self, trail_of: str) -> int:
        """How many trail states a playing frame shows (software WebGL pays for every segment drawn)."""
        return PLAYING_FOLLOWED_STATES if follows_one(trail_of) else PLAYING_TRAIL_STATES

    def palette(self, solved, highlight: int, trail_of: str, constraint_colors: bool) -> PlanarPalette:
        view = solved.view
        arms, ramp = emphasis_colors(view.num_states, view.num_samples, highlight, trail_of)
        if constraint_colors:  # every arm green where its constraints hold at that state, red where not
            arms = sample_tints(solved.state_violation, highlight)
        dots = np.broadcast_to(np.array(JOINT_SPACE_DOT, np.uint8), (view.num_samples, 3)).copy()
        dots[highlight] = ACCENT_DARK
        compare_arms = compare_trail = None
        compare = getattr(solved, "compare", None)
        if compare is not None:  # the same emphasis over the compared sampler's own states
            compare_arms, compare_ramp = emphasis_colors(compare.num_states, compare.num_samples, highlight, trail_of)
            compare_trail = planar_scene.trail_colors(compare_ramp, compare.num_links)
        return PlanarPalette(
            arms=arms, trail=planar_scene.trail_colors(ramp, view.num_links),
            tips=fade_colors(view.num_states, TIP_FAINT, TIP_DARK), dots=dots,
            compare_arms=compare_arms, compare_trail=compare_trail,
        )  # fmt: skip

    def solve_text(self, solved, state: int, highlight: int, reason: str, error: str | None) -> str:
        request = solved.request
        return readouts.solve_text(
            solved.view, state, highlight, sampler=request.sampler_label, seed=request.seed,
            refine_steps=request.refine_steps, solve_seconds=solved.solve_seconds, error=error, reason=reason,
        )  # fmt: skip

    def legend_entries(self, settings, *, constraint_colors: bool, view, solved, state=None) -> list[Entry]:
        """What each colour of the planar scene means now, for the panel's legend (and a recording's)."""
        if follows_one(settings.trail_of):
            trail = Entry(Swatch(ACCENT_DARK, faint=TRAIL_FAINT), "trail of the highlighted sample: t = T → 0", True)
            others = Entry(Swatch(OTHERS_FINAL, faint=FAINT), "the other samples (light)", True)
            # one dot at the step shown, pale near t = T and orange near t = 0: a ramp line read as a row of tips
            tips = Entry(
                Swatch(TIP_DARK, "dot", TIP_FAINT), "tip of the highlighted sample, at the step shown (pale → orange)"
            )
        else:
            trail = Entry(Swatch(DARK, faint=FAINT), "trails of all samples: t = T → 0", True)
            others = Entry(Swatch(DARK, faint=FAINT), "the other samples", True)
            tips = Entry(Swatch(TIP_DARK, "dot", TIP_FAINT), "tips of all samples, at the step shown (pale → orange)")
        highlighted = Entry(Swatch(ACCENT_DARK), "highlighted sample, at the step shown", True)
        entries = [trail] if settings.show_trail else []  # listed only while drawn, as every layer
        if constraint_colors:  # the arms are green or red then, the highlighted one in full
            if settings.show_trail and not follows_one(settings.trail_of):  # its trail stays blue among the grey
                entries.append(Entry(Swatch(ACCENT_DARK, faint=ACCENT_FAINT), "trail of the highlighted sample"))
            entries += [
                Entry(Swatch(HOLDS, faint=HOLDS_OTHERS), self.holds_text, True),
                Entry(Swatch(VIOLATES, faint=VIOLATES_OTHERS), self.violates_text, True),
            ]
        else:
            entries += [highlighted, others]
        entries.append(tips)
        entries += [*shown_layers(settings, solved, state), Entry(Swatch(TARGET_RED, "cross"), "target")]
        if settings.recording:  # a static page: what it draws alone (no joint space)
            return entries
        if settings.joint_space and view is not None:  # the square's marks, named apart from the target's ✕
            if view.num_links == 2:
                entries.append(Entry(Swatch(TARGET_RED, "cross"), "joint space: the target's two exact solutions, "
                                     "elbow up and elbow down (named beside them)"))  # fmt: skip
            else:
                entries.append(Entry(Swatch(JOINT_SPACE_DOT, "cross"), "joint space: the final samples"))
            entries.append(Entry(Swatch(JOINT_SPACE_DOT, "dot"), "joint space: the samples at the step shown"))
        return entries


def shown_layers(settings, solved, state=None) -> list[Entry]:
    """The legend's x̂0, refined, prior, comparison and obstacle entries, for both arm kinds, live and recorded: only
    while the scene draws them. x̂0 while the settings show it and, at a given state, the solve has a guess to draw
    there (none at t = T, nor at t = 0 where it is the final pose; `state` None: a recording, which plays them all),
    the refined poses when the solve shown was polished,
    the prior's draw while it is on screen, the compared sampler's poses beside the arm and the obstacles while drawn
    (none on a recording's page)."""
    entries = []
    drawn_estimate = state is None or solved is None or solved.view.estimate_at(state) is not None
    if settings.show_estimate and drawn_estimate:
        control = "" if settings.recording else " (show x̂0)"  # a recording has no panel to turn it on or off
        entries.append(Entry(Swatch(ESTIMATE), f"x̂0{control}: the denoiser's guess of the final pose"))
    if solved is not None and solved.view.refined:
        entries.append(Entry(Swatch(REFINED), "refined at t = 0 (DLS polish)"))
    if settings.prior and not settings.recording:
        entries.append(Entry(Swatch(PRIOR), "poses drawn from the prior"))
    if getattr(solved, "compare", None) is not None and not settings.recording:  # a test's solve may lack it
        sampler = solved.request.compare_sampler
        entries.append(Entry(Swatch(ACCENT_DARK, faint=ACCENT_FAINT), f"beside, titled: {sampler} from the same x_T"))
    if settings.obstacles and not settings.recording:
        entries.append(Entry(Swatch(OBSTACLE, "dot"), "obstacle: no link may touch it (drag its arrows)"))
    return entries
