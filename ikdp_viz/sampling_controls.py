"""The Sampling folder's controls that depend on each other: K and the highlight, the sampler and its steps.

A sampler that takes all T steps (DDPM) shows T on a disabled slider, the student its own few
(student.py); the steps the user chose for one that can skip some come back with it.
Each change asks for a solve.
"""

from __future__ import annotations

from ikdp.samplers import SAMPLERS, sampler_names
from ikdp_viz.panel import COMPARE_CHOICES, Panel, highlight_options
from ikdp_viz.student import STUDENT, TEACHER, student_sampling, switch_label


class SamplingControls:
    """K, the sampler, its steps and the refinement of one panel; `request_solve()` after each change."""

    def __init__(self, panel: Panel, request_solve, session):
        self.panel, self.request_solve, self.session = panel, request_solve, session
        self.chosen_steps = int(panel.steps.value)  # the steps a sampler that can skip some takes
        self._showing = False  # show_steps is moving the slider

    def offer_student(self) -> None:
        """The sampler and "compare with" lists, and the teacher/student button, for the session's model: the student
        first where there is one. Runs on the drawing loop (it writes controls)."""
        student, panel = self.session.student, self.panel
        extra = (STUDENT,) if student is not None else ()
        panel.sampler.options = extra + sampler_names()
        panel.learn.compare.options = COMPARE_CHOICES + ((TEACHER, STUDENT) if student is not None else ())
        if panel.sampler.value not in panel.sampler.options:
            panel.sampler.value = "ddpm"
        if panel.learn.compare.value not in panel.learn.compare.options:
            panel.learn.compare.value = "off"
        panel.teacher_student.visible = student is not None
        self.show_switch()

    def show_switch(self) -> None:
        student = self.session.student
        if student is not None:
            on_student = self.panel.sampler.value == STUDENT
            self.panel.teacher_student.label = switch_label(on_student, self.session.solver, student)

    def on_switch(self) -> None:
        """The button: the student's few steps <-> the teacher's full DDPM (one click, to compare the two)."""
        self.panel.sampler.value = "ddpm" if self.panel.sampler.value == STUDENT else STUDENT
        self.on_sampler()  # the loop wrote the dropdown: what follows from it is the loop's to do

    def on_samples(self) -> None:
        options = highlight_options(int(self.panel.samples.value))
        current = self.panel.highlight.value
        self.panel.highlight.options = options
        if current not in options:
            self.panel.highlight.value = "best"
        self.request_solve()

    def on_sampler(self) -> None:
        self.show_steps()
        self.show_switch()
        self.request_solve()

    def fixed_steps(self) -> int | None:
        """The steps the chosen sampler always takes: T for DDPM, the student's own; None for one that can skip."""
        choice = str(self.panel.sampler.value)
        if choice == STUDENT and self.session.student is not None:
            return student_sampling(self.session.student)[1]
        if choice not in SAMPLERS:  # the student of a model just closed: offer_student follows
            return None
        return None if SAMPLERS[choice].supports_steps else int(self.panel.steps.max)

    def on_steps(self) -> None:
        steps = self.panel.steps
        if self._showing or (steps.disabled and int(steps.value) == self.fixed_steps()):
            return  # show_steps, or the loop fitting the slider to a new model's T: no one's choice
        self.chosen_steps = int(steps.value)  # a script's or the command line's, for when a sampler can skip
        if steps.disabled:
            self.show_steps()  # this sampler takes all T: that is what the slider says
        else:
            self.request_solve()

    def show_steps(self) -> None:
        """The steps slider: the user's choice for a sampler that can skip steps; else disabled at T, the steps
        it does take (not a stale number left from another sampler). The user's choice comes back with such a
        sampler."""
        steps = self.panel.steps
        fixed = self.fixed_steps()
        if fixed is not None and not steps.disabled:
            self.chosen_steps = int(steps.value)
        steps.disabled = fixed is not None
        shown = fixed if fixed is not None else min(self.chosen_steps, steps.max)
        if steps.value != shown:
            self._showing = True  # not a user's change: no solve of its own
            try:
                steps.value = shown
            finally:
                self._showing = False

    def on_refine(self) -> None:
        self.panel.refine_steps.disabled = not self.panel.refine.value
        self.request_solve()
