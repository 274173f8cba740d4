"""The state of one viewer session: the model, the target, and the panel's sampling settings as a request.

Every browser tab shares one session. Moves and model switches come from viser's
event loop, its callback threads and scripts at once; the lock makes each change
of the target one step, so the order of the targets is the order of the requests.
"""

from __future__ import annotations

import random
import threading
import time

import numpy as np

import ikdp
from ikdp.samplers import SAMPLERS
from ikdp_viz.arm_kinds import arm_kind
from ikdp_viz.panel import Panel
from ikdp_viz.solving import SolveRequest
from ikdp_viz.student import STUDENT, TEACHER, distillation_target, student_sampling


def initial_target(solver: ikdp.Solver, target=None) -> np.ndarray:
    """`target` clamped into the solver's workspace, or the arm kind's first target when None."""
    return arm_kind(solver).initial_target(solver, target)


class Session:
    """The model and the target; `lock` is held while either changes and its consequences are posted."""

    def __init__(self, solver: ikdp.Solver, target=None, student: ikdp.Solver | None = None):
        self.lock = threading.RLock()
        self.solver = solver  # the model the newest requests use
        self.student = student  # its few-step student, the sampler "student" (student.py); None: none here
        self.target = initial_target(solver, target)  # planar (2,), chain pose (7,); inside the workspace
        self.target_clamped = False  # the point asked for lay outside the workspace

    def move(self, point, *, from_gizmo: bool) -> tuple[np.ndarray, bool, bool]:
        """Clamp `point` into the workspace and make it the target: (target, clamped, changed). Hold `lock`."""
        target, clamped = arm_kind(self.solver).clamp(self.solver, point)
        changed = not np.array_equal(target, self.target)
        # A drag past the boundary ends on the boundary point the app put the gizmo at: still the clamped request.
        clamped = clamped or (not changed and from_gizmo and self.target_clamped)
        self.target, self.target_clamped = target, clamped
        return target, clamped, changed

    def request(
        self,
        panel: Panel,
        *,
        arrival: float | None = None,
        animate: bool = True,
        constraints: tuple = (),
        chosen_steps: int | None = None,
        follow_from: np.ndarray | None = None,
    ) -> SolveRequest:
        """A solve of the current target with the panel's settings (a new seed first, if the panel asks).

        `chosen_steps`: the steps the user chose for a sampler that can skip some, which the panel's slider
        does not show while DDPM runs (it shows T); None reads the slider.
        """
        # a new seed each solve when the panel asks (the app has the loop show it)
        seed = random.randrange(2**31) if panel.new_seed.value else int(panel.seed.value)
        choice = str(panel.sampler.value)
        solver, sampler, steps = self.sampling(choice, int(panel.steps.value))
        return SolveRequest(
            solver=solver,
            target=self.target.copy(),
            num_samples=int(panel.samples.value),
            sampler=sampler,
            steps=steps,
            refine_steps=int(panel.refine_steps.value) if panel.refine.value else 0,
            seed=seed,
            arrival=time.perf_counter() if arrival is None else arrival,
            animate=animate,
            **self.compare_settings(panel, choice, chosen_steps),
            constraints=tuple(constraints),
            student=self.student,
            teacher=None if solver is self.solver else self.solver,
            follow_from=follow_from,
            target_clamped=self.target_clamped,
        )

    def sampling(self, choice: str, steps: int | None) -> tuple[ikdp.Solver, str, int | None]:
        """The dropdown's `choice` as (model, sampler, steps): the student's own few steps, or the model's sampler
        with `steps` where it can skip some (None: all T)."""
        if choice == STUDENT and self.student is not None:
            return (self.student, *student_sampling(self.student))
        if choice not in SAMPLERS:
            raise ValueError(f"sampler: expected one of {tuple(SAMPLERS)}, got {choice!r}")
        return self.solver, choice, steps if SAMPLERS[choice].supports_steps else None

    def compare_settings(self, panel: Panel, choice: str, chosen_steps: int | None = None) -> dict:
        """The comparison the panel asks for: another sampler (or the student, or from it the teacher) from the
        same x_T, unless it is the sampler itself."""
        other = str(panel.learn.compare.value)
        if other == choice:  # nothing drawn beside it: said, or the choice looks broken
            return {"compare_note": f"compare with: **{other}** is the sampler shown: nothing to compare"}
        if other == "off" or (other not in SAMPLERS and other not in (STUDENT, TEACHER)):
            return {}
        if other in (STUDENT, TEACHER) and self.student is None:
            return {}
        if other == TEACHER:  # the teacher's run the student was distilled from, beside either
            sampler, steps, spacing = distillation_target(self.student)
            return {"compare_sampler": sampler, "compare_steps": steps, "compare_solver": self.solver,
                    "compare_spacing": spacing}  # fmt: skip
        steps = int(panel.steps.value) if chosen_steps is None else chosen_steps
        solver, sampler, steps = self.sampling(other, steps)
        return {"compare_sampler": sampler, "compare_steps": steps, "compare_solver": solver}
