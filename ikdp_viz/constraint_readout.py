"""The Constraints folder's readout after a solve (markdown), from plain values: no viser here.

What the target asks, how many samples meet the constraints and from which step the kept one
does, follow mode's step and jumps, and, in words, why nothing reaches or meets:
a lock clamped or wrapped, no sample meeting the constraints, no sample reaching the target.
"""

from __future__ import annotations

from ikdp_viz.constraint_scene import first_holding_state, holds


def readout_text(solved, choice: int, jump: float | None, largest_jump: float, lock_notes: list[str], *,
                 reaches: bool, switches: int = 0, switched: bool = False) -> str:  # fmt: skip
    """The readout for `solved` with sample `choice` kept; `reaches`: some returned pose reaches the target;
    `switched`: follow mode's kept pose changed branch at this target, `switches` times so far."""
    lines = []
    measure = getattr(solved.view, "rotation_measure", "rotation")
    if measure == "none":
        lines.append("target: **position only**, any hand rotation")
    elif measure != "rotation":
        lines.append(f"target: the hand's **{measure} free**, any turn about it")
    lines += [f"lock: {note}" for note in lock_notes]
    if solved.state_violation is not None:
        count = len(solved.state_violation[-1])
        met = int(holds(solved.state_violation[-1]).sum())
        first = first_holding_state(solved.state_violation[:, choice])
        states = len(solved.state_violation) - 1
        held = "never" if first is None else f"from state {first} of {states} (t = {solved.view.labels[first]})"
        lines.append(f"constraints met by {met} of {count} raw samples")
        lines.append(f"sample {choice + 1}: holds {held}")
    lines += unmet_reasons(solved, reaches=reaches)
    if solved.pull_missed is not None:
        lines.append(
            f"**stay near: every pulled sample missed the target** (best {solved.pull_missed:.3g} away); "
            "shown: the same noise solved without the pull"
        )
    if jump is not None and solved.followed is not None:
        lines.append(followed_text(solved.followed, choice))
    if jump is not None:
        lines.append(f"joint jump {jump:.3f} rad, largest so far **{largest_jump:.3f} rad**")
        if switched:
            lines.append("**branch switch**: no sample continues the last pose; the arm jumps to another solution here")
        if switches:
            lines.append(f"branch switches so far: {switches}")
    return "  \n".join(lines) if lines else "No constraint."


def followed_text(step, choice: int) -> str:
    """What follow mode (ikdp.tracking's step) kept for this target."""
    if not bool(step.kept.reached[0]):
        return ("**follow: no pose reaches the target**; the arm stays on its branch, stretched toward it "
                f"(sample {choice + 1}'s returned pose)")  # fmt: skip
    if step.sample is None:
        return (f"follow: kept the last pose moved onto the target, nearer than every sample (drawn as sample "
                f"{choice + 1}'s returned pose)")  # fmt: skip
    return f"follow: kept sample {choice + 1}, the nearest of those that reach the target"


# what each checked constraint's failure means to a user, and what to do (ikdp constraint name -> words)
FAILING_WORDS = {
    "obstacles": ("touches an obstacle", "move it, or make it smaller"),
    "locked_joints": ("is off a locked joint's value", "unlock it or change its value"),
}


def unmet_reasons(solved, *, reaches: bool | None = None) -> list[str]:
    """Why no sample meets the constraints, or reaches the target, in words: which constraint fails in how many
    of the K raw samples at t = 0, and whether the locks keep the hand from the target. [] when
    some sample meets them and reaches. Both readouts say it: the main one and the Constraints folder's."""
    names = {item.name for item in solved.request.constraints}
    if not names:
        return []
    reaches = solved.reaches if reaches is None else reaches
    lines = []
    if solved.state_violation is not None and not holds(solved.state_violation[-1]).any():
        count = solved.state_violation.shape[1]
        why = []
        for name, violation in solved.final_violations:
            failing = int((~holds(violation)).sum())
            if failing:
                failure, remedy = FAILING_WORDS.get(name, (f"fails {name.replace('_', ' ')}", "relax it"))
                who = "every sample" if failing == count else f"{failing} of {count} samples"
                why.append(f"{who} {failure}: {remedy}")
        if not why and "obstacles" in names:  # no per-constraint split (an older solve): the obstacle is the one
            failure, remedy = FAILING_WORDS["obstacles"]
            why.append(f"every one {failure}: {remedy}")
        lines.append(f"**no sample meets the constraints**: {'; '.join(why) or 'try more samples (K)'}")
    caused = not reaches and bool(solved.reaches_unconstrained)  # the same noise, freed, reaches
    if caused and "locked_joints" in names:
        lines.append("**no sample reaches the target with these locks**: the locked joints keep the hand from it; "
                     "unlock one or change its value")  # fmt: skip
    elif caused and "obstacles" in names:
        lines.append("**no sample reaches the target past the obstacles**: move them, or make them smaller")
    return lines
