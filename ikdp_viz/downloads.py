"""What a tab can take away: the solve on screen as a GIF and a PNG (export.py), or as one HTML page (record.py).

Both read the solve on screen and the view settings on the drawing loop's thread (one
snapshot, as a frame is built), then render on the thread of the tab's click.
"""

from __future__ import annotations

from pathlib import Path

import viser

from ikdp_viz.record import file_name


def export_picture(solved, settings, solver, legend=None):
    """The export.Drawing of `solved` as `settings` show it: the arm kind's flat picture, colours and clock.

    `legend`: the entries of the frame on screen (frame.Frame.legend), of which the picture lists those it draws
    too (`Entry.flat`); None: built for `settings` as a frame would."""
    from ikdp_viz.arm_kinds import arm_kind
    from ikdp_viz.clock import solve_noise_levels, state_offsets
    from ikdp_viz.export import drawing
    from ikdp_viz.frame import highlighted_sample
    from ikdp_viz.legend import Entry, Swatch
    from ikdp_viz.style import TARGET_RED

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
             f"{kind.target_words(request.target)}")  # fmt: skip
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
        from ikdp_viz.export import write_gif, write_trail_png

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
