"""What a tab can take away: the solve on screen as a GIF and a PNG (downloads.py), or as one HTML page (record.py).

Both read the solve on screen and the view settings on the drawing loop's thread (one
snapshot, as a frame is built), then render on the thread of the tab's click.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import viser

from ikdp_viz.planar_scene import emphasis_colors, follows_one
from ikdp_viz.record import file_name
from ikdp_viz.style import REACH_RING_HEX, TARGET_RED_HEX


def export_picture(solved, settings, solver, legend=None):
    """The export.Drawing of `solved` as `settings` show it: the arm kind's flat picture, colours and clock.

    `legend`: the entries of the frame on screen (frame.Frame.legend), of which the picture lists those it draws
    too (`Entry.flat`); None: built for `settings` as a frame would."""
    from ikdp_viz.arm_kinds import arm_kind
    from ikdp_viz.frame import highlighted_sample, solve_noise_levels, state_offsets
    from ikdp_viz.style import TARGET_RED, Entry, Swatch

    kind, view, request = arm_kind(solver), solved.view, solved.request
    highlight = highlighted_sample(settings.highlight, solved)
    constraint_colors = settings.color_by_constraint and solved.state_violation is not None
    palette = kind.palette(solved, highlight, settings.trail_of, constraint_colors)
    polylines, target, circle, _ = kind.flat_picture(solved)
    sigmas = solve_noise_levels(solver, view)
    if legend is None:
        legend = kind.legend_entries(settings, constraint_colors=constraint_colors, view=view, solved=solved)
    legend = [entry for entry in legend if entry.flat]
    legend.append(Entry(Swatch(TARGET_RED, "cross"), "target"))  # fmt: skip
    title = (f"IKDP {request.sampler_label}, K = {view.num_samples}, seed {request.seed}: "
             f"{kind.target_words(request.target, solver.arm)}")  # fmt: skip
    return drawing(
        solved, polylines, target, circle=circle, highlight=highlight, trail_of=settings.trail_of,
        arms=kind.arm_colors(palette), offsets=state_offsets(sigmas, settings.clock, settings.seconds), title=title,
        legend=legend,
    )  # fmt: skip


class Downloads:
    """The Export and Share buttons of one viewer. The files render on the thread of the tab's click; what the tab
    sees of it (the Share button's label, the Export notification) is written by the drawing loop (`writer.run`),
    which also decides, by its own flag, that one export renders at a time: no lock."""

    def __init__(self, writer, panel):
        self.writer, self.panel = writer, panel
        self.share_label = panel.learn.share.label  # the button's label when it is not recording
        self._exporting = False  # an export is rendering (read and set on the drawing loop's thread only)
        self._export_notes: dict[int, viser.NotificationHandle] = {}  # client id -> its export's notification

    def snapshot(self, what: str):
        """(solve on screen, view settings, solver, frame) read on the drawing loop's thread, or ValueError."""
        done: list = []
        self.writer.run(lambda writer: done.append((writer.solved, writer.settings(), writer.solver, writer.frame)))
        solved, settings, solver, frame = done[0]  # one snapshot: the four belong together
        if solved is None:
            raise ValueError(f"{what}: nothing solved yet")
        return solved, settings, solver, frame

    def export(self, folder: Path, progress=None) -> tuple[Path, Path]:
        """Write the solve on screen as `<stem>.gif` (the denoising) and `<stem>_trail.png` into `folder`, for
        either arm, with the viewer's colours, clock and highlighted sample, and the legend of the frame on screen.

        `progress(done, total)` is called after each GIF frame (export.write_gif).
        """

        solved, settings, solver, frame = self.snapshot("export")
        same = frame is not None and frame.solved is solved  # the frame the snapshot holds is of this solve
        picture = export_picture(solved, settings, solver, legend=frame.legend if same else None)
        stem = file_name(solved).removesuffix(".html")
        gif = write_gif(picture, Path(folder) / f"{stem}.gif", seconds=settings.seconds, progress=progress)
        png = write_trail_png(picture, Path(folder) / f"{stem}_trail.png")
        return gif, png

    def on_export(self, event: viser.GuiEvent) -> None:
        """Export into a temporary folder and save both files in the downloads of the tab that asked.

        The tab sees one notification per export, replacing its last one: the GIF's frames as they
        render, then the two names. The files are saved at once (viser's `save_immediately`): without
        it viser shows a link per file to click, and the links pile up.
        """
        import tempfile

        client = event.client
        if client is None:
            return
        started: list = []
        self.writer.run(lambda _: started.append(self._start_export(client)))
        note = started[0]
        if note is None:
            return  # another export is rendering: the notification says so
        tell = lambda **fields: self.writer.run(lambda _: note_fields(note, fields), wait=False)
        try:
            progress = lambda done, total: tell(body=f"rendering the GIF: frame {done} of {total}")
            with tempfile.TemporaryDirectory() as folder:
                paths = self.export(Path(folder), progress=progress)
                tell(body="sending the files")
                for path in paths:
                    client.send_file_download(path.name, path.read_bytes(), save_immediately=True)
            # a zero-width space after each "_" lets the long names wrap instead of being cut off with "..."
            names = [path.name.replace("_", "_\u200b") for path in paths]
            tell(title="Exported to your downloads", body=" and ".join(names))
        except ValueError as error:
            tell(title="Export failed", body=str(error), color="red")
        finally:
            tell(loading=False, with_close_button=True, auto_close_seconds=8.0)
            self.writer.run(lambda _: setattr(self, "_exporting", False), wait=False)

    def _start_export(self, client) -> viser.NotificationHandle | None:
        """Drawing loop's thread: the tab's notification for a new export (its last one removed); None when another
        export is rendering, which the notification then says."""
        previous = self._export_notes.pop(client.client_id, None)
        if previous is not None:  # popped, so never removed twice
            previous.remove()
        note = client.add_notification("Export", "starting", loading=True, with_close_button=False)
        self._export_notes[client.client_id] = note
        if self._exporting:
            note_fields(note, dict(body="another export is rendering; try again", loading=False,
                                   with_close_button=True, auto_close_seconds=5.0))  # fmt: skip
            return None
        self._exporting = True
        return note

    def share(self) -> tuple[str, str]:
        """The solve on screen as one self-contained HTML page (record.py) with the panel's view: (file name, page)."""
        from ikdp_viz.record import record_html

        solved, settings, _, _ = self.snapshot("share")
        return file_name(solved), record_html(solved, settings)

    def on_share(self, event: viser.GuiEvent) -> None:
        """Record the solve on screen and send the page to the tab that asked; the button says while it works."""
        if event.client is None or self.writer.solved is None:
            return
        self.writer.run(lambda writer: button_state(writer.panel.learn.share, "Recording the denoising...", True))
        try:
            name, page = self.share()
            event.client.send_file_download(name, page.encode("utf-8"), save_immediately=True)
        finally:
            self.writer.run(lambda writer: button_state(writer.panel.learn.share, self.share_label, False))


def note_fields(note, fields: dict) -> None:
    for name, value in fields.items():
        setattr(note, name, value)


def button_state(button, label: str, disabled: bool) -> None:
    button.label, button.disabled = label, disabled


# A solve on screen, written to files for a slide: the denoising as a GIF and the trail figure as a PNG.
TITLE_BAND = 40  # pixels above the trail PNG's picture, for its title


@dataclass(frozen=True)
class Drawing:
    """What the files draw, in the picture's plane: every state's polylines and how to colour them."""

    polylines: np.ndarray  # (S+1, K, P, 2) each sample's joints at each state, projected
    target: np.ndarray  # (E, 2) the target (one per end effector), projected
    half_width: float  # the picture shows [-w, w] around `center`
    center: np.ndarray  # (2,)
    circle: float | None  # the workspace boundary's radius (planar), or None
    arms: np.ndarray  # (S+1, K, 3) uint8 each sample's colour at each state (the viewer's)
    trail: np.ndarray  # (S+1, K, 3) uint8 each sample's trail colour at each state
    highlight: int  # the sample followed
    follows_one: bool  # only the followed sample's trail is drawn (the default picture)
    labels: np.ndarray  # (S+1,) diffusion time of each state
    offsets: np.ndarray  # (S+1,) seconds from state 0 at which each state shows (frame.py)
    title: str  # what was solved
    legend: tuple  # legend.Entry of what each colour means

    @property
    def num_states(self) -> int:
        return self.polylines.shape[0]


def drawing(solved, polylines, target, *, circle, highlight: int, trail_of: str, arms, offsets, title, legend):
    """A Drawing of `solved` with the viewer's colours: `arms` (S+1, K, 3), the trail ramp from `trail_of`."""
    view = solved.view
    _, trail = emphasis_colors(view.num_states, view.num_samples, highlight, trail_of)
    targets = np.asarray(target, dtype=np.float64).reshape(-1, 2)
    points = np.concatenate([np.asarray(polylines).reshape(-1, 2), targets])
    low, high = np.nanmin(points, axis=0), np.nanmax(points, axis=0)  # NaN: a break between a tree's chains
    if circle is not None:
        low, high = np.minimum(low, -circle), np.maximum(high, circle)
    center = (low + high) / 2
    return Drawing(
        polylines=np.asarray(polylines), target=targets, half_width=1.05 * float(np.max(high - low)) / 2,
        center=center, circle=circle, arms=arms, trail=trail, highlight=highlight, follows_one=follows_one(trail_of),
        labels=view.labels, offsets=np.asarray(offsets), title=title, legend=tuple(legend),
    )  # fmt: skip


def _figure(picture: Drawing, size_pixels: int, band: int = 0):
    """A figure `size_pixels` square for the picture and `band` pixels above it (free for a title)."""
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle

    dpi = 100
    figure = Figure(figsize=(size_pixels / dpi, (size_pixels + band) / dpi), dpi=dpi)
    axes = figure.add_axes((0, 0, 1, size_pixels / (size_pixels + band)))
    (cx, cy), half = picture.center, picture.half_width
    axes.set_xlim(cx - half, cx + half)
    axes.set_ylim(cy - half, cy + half)
    axes.set_aspect("equal")
    axes.axis("off")
    if picture.circle is not None:
        axes.add_patch(Circle((0, 0), picture.circle, fill=False, color=REACH_RING_HEX, linewidth=0.8))
    return figure, axes


def _draw_state(axes, picture: Drawing, state: int, *, trail: bool) -> None:
    """The trail up to `state` (the viewer's ramp; the followed sample's alone by default) and the arms at `state`."""
    num_samples = picture.polylines.shape[1]
    trail_samples = [picture.highlight] if picture.follows_one else range(num_samples)
    if trail:
        for shown in range(state):
            for sample in trail_samples:
                joints = picture.polylines[shown, sample]  # (P, 2)
                axes.plot(joints[:, 0], joints[:, 1], color=picture.trail[shown, sample] / 255, linewidth=0.5,
                          zorder=shown)  # fmt: skip
    top = picture.num_states
    for sample in range(num_samples):
        if sample != picture.highlight:
            joints = picture.polylines[state, sample]
            axes.plot(joints[:, 0], joints[:, 1], color=picture.arms[state, sample] / 255, linewidth=1.5, zorder=top)
    chosen = picture.polylines[state, picture.highlight]
    color = picture.arms[state, picture.highlight] / 255
    axes.plot(chosen[:, 0], chosen[:, 1], color=color, linewidth=2.5, marker="o", markersize=3, zorder=top + 1)
    axes.plot(picture.target[:, 0], picture.target[:, 1], linestyle="none", marker="x", color=TARGET_RED_HEX,
              markersize=12, mew=3, zorder=top + 2)  # fmt: skip


def write_trail_png(picture: Drawing, path: Path, *, size_pixels: int = 800) -> Path:
    """The paper's Fig. "vis" as the viewer draws it at t = 0, with the legend, under a band with the title:
    `size_pixels` square for the picture, `TITLE_BAND` pixels more on top
    (a title inside it ran over the reach circle)."""
    figure, axes = _figure(picture, size_pixels, band=TITLE_BAND)
    _draw_state(axes, picture, picture.num_states - 1, trail=True)
    figure.text(0.02, 1 - 0.5 * TITLE_BAND / (size_pixels + TITLE_BAND), picture.title, ha="left", va="center",
                fontsize=11)  # fmt: skip
    handles = [_legend_handle(entry) for entry in picture.legend]
    axes.legend(handles=handles, loc="lower left", fontsize=7, frameon=True, framealpha=0.85)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path)
    return path


def _legend_handle(entry):
    from matplotlib.lines import Line2D

    marker = {"dot": "o", "cross": "x"}.get(entry.swatch.shape)
    color = np.array(entry.swatch.color) / 255
    if marker is not None:
        return Line2D([], [], color=color, marker=marker, linestyle="none", label=entry.text)
    return Line2D([], [], color=color, linewidth=2.5, label=entry.text)


def gif_states(offsets: np.ndarray, seconds: float, max_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """(states, durations in s) of a GIF on the viewer's clock: frames evenly spaced in time, each the state the
    clock has reached then; a state reached by several frames shows once, for their time together."""
    times = np.linspace(0.0, seconds, max_frames, endpoint=False)
    reached = np.clip(np.searchsorted(offsets, times, side="right") - 1, 0, len(offsets) - 1)
    states, first = np.unique(reached, return_index=True)
    ends = np.append(times[first[1:]], seconds)
    durations = ends - times[first]
    states = np.append(states, len(offsets) - 1) if states[-1] != len(offsets) - 1 else states
    durations = np.append(durations, 1.0) if len(durations) < len(states) else durations
    return states, durations


def write_gif(picture: Drawing, path: Path, *, seconds: float = 4.0, size_pixels: int = 480, max_frames: int = 41,
              progress=None) -> Path:  # fmt: skip
    """The denoising from t = T to 0 as a looping GIF of at most `max_frames` frames over `seconds`, on the viewer's
    clock. Each frame says its diffusion time `t` (top left). `progress(done, total)`, if given, is called after each
    frame is drawn: the panel shows it while a long GIF renders."""
    import imageio.v2 as imageio
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    if seconds <= 0 or max_frames < 2:
        raise ValueError(f"seconds, max_frames: expected > 0 and >= 2, got {seconds}, {max_frames}")
    states, durations = gif_states(picture.offsets, seconds, max_frames)
    frames = []
    for state in states:
        figure, axes = _figure(picture, size_pixels)
        _draw_state(axes, picture, int(state), trail=False)
        axes.text(0.03, 0.97, time_label(picture, int(state)), transform=axes.transAxes, ha="left", va="top",
                  fontsize=16)  # fmt: skip
        canvas = FigureCanvasAgg(figure)
        canvas.draw()
        frames.append(np.asarray(canvas.buffer_rgba())[..., :3].copy())
        if progress is not None:
            progress(len(frames), len(states))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    imageio.mimsave(path, frames, duration=[1000 * float(value) for value in durations], loop=0)
    return path


def time_label(picture, state: int) -> str:
    """What a GIF frame says: its diffusion time, t = T for pure noise down to t = 0."""
    return f"t = {picture.labels[state]:g}"
