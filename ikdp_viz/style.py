"""The viewer's shared colours and line widths (RGB 0..255, screen pixels): one place for what both arms draw."""

from __future__ import annotations

TARGET_RED = (220, 25, 25)
GRID_CELL = (236, 236, 236)  # grid lines every half bone length (a robot: every cell)
GRID_SECTION = (212, 212, 212)  # grid lines every mean bone length (a robot: every fifth cell)
ESTIMATE = (150, 80, 200)  # the denoiser's x̂0, ghosted
PRIOR = (150, 100, 50)  # poses drawn from the training prior
LINE_PIXELS = 1.5  # trail line thickness, screen pixels
ARM_PIXELS = 5.0  # the K arms' links, screen pixels (the joints' spheres are about twice as wide at the default zoom)
OBSTACLE = (190, 30, 150)  # magenta: an obstacle dropped on the arm stays apart from the red of a failing pose
COMPARE_STROKE = "#2a9d5c"  # the chart's line of the compared sampler
