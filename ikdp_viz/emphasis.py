"""What the default picture stresses, as the paper's figure does: one sample's denoising, the others in the background.

Drawn with every sample's trail, K = 16 poses at 81 states are a grey mass (5,184 line
segments; K = 64 is solid black) in which no single denoising can be followed. So by
default the trail is the highlighted sample's alone, from faint (t = T) to dark blue
(t = 0), and the other samples are drawn light: their final poses show the spread of
the solutions without hiding the one being followed. "all samples" keeps the old
picture (every trail, every arm dark at t = 0). No viser here.
"""

from __future__ import annotations

import numpy as np

from ikdp_viz.scene import ACCENT_DARK, FAINT, fade_colors, sample_colors

TRAIL_CHOICES = ("highlighted", "all samples")  # the panel's "trail of" dropdown, the default first
OTHERS_FINAL = (185, 185, 185)  # the samples not highlighted at t = 0, with the trail of the highlighted one only
# The followed trail's noisy end: nearly the page's white. Its first states are random poses over half the
# workspace; at the accent's own faint blue they were a pale tangle that read as more samples, while this
# leaves the last states, where the pose forms, to stand out from the grey final samples.
TRAIL_FAINT = (236, 242, 251)
TRAIL_GAMMA = 3.0  # and it darkens later than the arms' ramp: the pale noisy half recedes behind the grey finals


def follows_one(trail_of: str) -> bool:
    """The trail and the dark colours belong to the highlighted sample alone (the default picture)."""
    if trail_of not in TRAIL_CHOICES:
        raise ValueError(f"trail_of: expected one of {TRAIL_CHOICES}, got {trail_of!r}")
    return trail_of == TRAIL_CHOICES[0]


def emphasis_colors(num_states: int, num_samples: int, highlight: int, trail_of: str) -> tuple[np.ndarray, np.ndarray]:
    """(arm colours, trail colours), each (S+1, K, 3) uint8: the colour of each sample at each state.

    Following one sample, its trail runs from faint to dark blue while its arm is dark blue at every
    state (so the pose being followed is never lost in the noise), and the other samples fade from
    faint to a light grey. With "all samples", arms and trails share the faint-to-dark ramp.
    """
    if not follows_one(trail_of):
        colors = sample_colors(num_states, num_samples, highlight)
        return colors, colors
    trail = np.repeat(fade_colors(num_states, FAINT, OTHERS_FINAL)[:, None], num_samples, axis=1)
    trail[:, highlight] = fade_colors(num_states, TRAIL_FAINT, ACCENT_DARK, gamma=TRAIL_GAMMA)
    arms = trail.copy()
    arms[:, highlight] = ACCENT_DARK
    return arms, trail


def estimate_rows(num_samples: int, highlight: int, trail_of: str) -> slice:
    """The samples whose x̂0 is ghosted: the highlighted one's alone when it is followed (16 are a tangle)."""
    return slice(highlight, highlight + 1) if follows_one(trail_of) else slice(0, num_samples)


def trail_rows(num_samples: int, num_segments: int, highlight: int, trail_of: str) -> slice:
    """The trail's rows (of K * num_segments, sample-major) to draw: the highlighted sample's, or all."""
    if not follows_one(trail_of):
        return slice(0, num_samples * num_segments)
    return slice(highlight * num_segments, (highlight + 1) * num_segments)
