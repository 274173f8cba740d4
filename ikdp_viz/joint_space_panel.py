"""The panel's joint-space controls: the view's toggle and, for arms of more than two links, the two joints shown."""

from __future__ import annotations

from dataclasses import dataclass

import viser

from ikdp_viz.words import JOINT_SPACE_HINT

DEFAULT_GRID = 20  # field arrows per side of the square


def joint_labels(num_joints: int) -> tuple[str, ...]:
    """Dropdown options, one per link heading, counted from 1 as in the readouts: θ1 .. θN."""
    return tuple(f"θ{number}" for number in range(1, num_joints + 1))


@dataclass
class JointSpaceControls:
    folder: viser.GuiFolderHandle  # hidden for arms the view does not draw (robots)
    show: viser.GuiCheckboxHandle
    first: viser.GuiDropdownHandle  # the joint along the square's x axis
    second: viser.GuiDropdownHandle  # the joint along its y axis
    grid: viser.GuiSliderHandle  # arrows per side

    def joints(self) -> tuple[int, int]:
        """The 0-based pair shown; the second moves off the first when both name the same joint."""
        options = self.first.options
        first, second = options.index(self.first.value), options.index(self.second.value)
        if first == second:
            second = (first + 1) % len(options)
        return first, second

    def keep_apart(self, moved: viser.GuiDropdownHandle) -> None:
        """`moved` was set to the joint the other dropdown names: move the other to the next joint, on screen too.

        A square of one joint against itself is a line; the view used to draw the next joint silently while
        both dropdowns said the same one.
        """
        other = self.second if moved is self.first else self.first
        if moved.value != other.value:
            return
        options = tuple(moved.options)
        other.value = options[(options.index(moved.value) + 1) % len(options)]

    def fit(self, num_joints: int) -> None:
        """Offer the joints of an arm of `num_joints` links; with two there is nothing to choose."""
        options = joint_labels(max(num_joints, 2))
        if tuple(self.first.options) != options:
            self.first.options, self.second.options = options, options
            self.first.value, self.second.value = options[0], options[1]
        for dropdown in (self.first, self.second):
            if dropdown.disabled != (num_joints <= 2):  # called with every frame: write only a change
                dropdown.disabled = num_joints <= 2


def build_joint_space_controls(gui: viser.GuiApi) -> JointSpaceControls:
    with gui.add_folder("Joint space") as folder:
        show = gui.add_checkbox(
            "joint space view", False, hint=JOINT_SPACE_HINT,
        )  # fmt: skip
        options = joint_labels(2)
        first = gui.add_dropdown("x: joint", options, initial_value=options[0], disabled=True)
        second = gui.add_dropdown("y: joint", options, initial_value=options[1], disabled=True)
        grid = gui.add_slider("field grid", min=4, max=40, step=1, initial_value=DEFAULT_GRID)
    controls = JointSpaceControls(folder, show, first, second, grid)
    first.on_update(lambda _: controls.keep_apart(first))  # before the app's redraw, which reads the pair
    second.on_update(lambda _: controls.keep_apart(second))
    return controls
