"""One writer of the panel: every panel output, a control's own state included, is written by the drawing loop.

Callbacks only record intent, so that no two threads race to write one control. The Share button's label, the
Export notification and some controls' own states (the highlight's options, the steps slider, a lock field
enabled, the seed shown) were once written from the thread of the callback; here every update viser sends for the
panel is traced to its thread.
"""

from __future__ import annotations

import threading
from types import SimpleNamespace

import viser
from viz_helpers import running_app, settle

import ikdp

LOOP_THREAD = "ikdp-viz-scene"  # intent.py names the drawing loop's thread so


class FakeTab:
    """A browser tab as a click's event carries it: takes files and shows notifications, noting the threads."""

    client_id = 7

    def __init__(self, threads: list[str]):
        self.threads, self.files = threads, []

    def send_file_download(self, name, content, save_immediately=False):
        self.files.append(name)

    def add_notification(self, *args, **kwargs):
        self.threads.append(threading.current_thread().name)
        tab = self

        class Note:
            def __setattr__(self, name, value):
                tab.threads.append(threading.current_thread().name)
                object.__setattr__(self, name, value)

            def remove(self):
                tab.threads.append(threading.current_thread().name)

        return Note()


def test_every_panel_output_is_written_by_the_drawing_loop(tiny_checkpoint, tmp_path):
    with running_app(ikdp.load(tiny_checkpoint), animation_seconds=0.0) as app:
        settle(app)
        writes: list[tuple[str, dict]] = []
        interface = app.server.gui._websock_interface
        send = interface.queue_message
        typed = {"uuid": None}  # the control a user is setting: its own value is the input, not an output

        def traced(message):
            if isinstance(message, viser._messages.GuiUpdateMessage):
                if message.uuid == typed["uuid"]:
                    typed["uuid"] = None  # viser sends the input first, then runs the callbacks
                else:
                    writes.append((threading.current_thread().name, message.updates))
            return send(message)

        def user_sets(handle, value) -> None:
            typed["uuid"] = handle._impl.uuid
            handle.value = value  # its callbacks run on this thread, as on viser's callback pool
            typed["uuid"] = None

        interface.queue_message = traced
        controls = app.constraint_controls
        try:
            # each as viser's callback pool would run it: on a thread that is not the loop's
            user_sets(app.panel.samples, 4)  # the highlight's options
            user_sets(app.panel.sampler, "ddim")  # the steps slider enabled, at the steps chosen
            user_sets(app.panel.sampler, "ddpm")  # ... and back at T, disabled
            user_sets(app.panel.refine, True)  # the refine steps enabled
            user_sets(controls.lock_boxes[0], True)  # its value field enabled
            user_sets(controls.follow, True)
            settle(app)
            user_sets(controls.follow, False)  # the highlight back to "best"
            user_sets(app.panel.new_seed, True)
            app.request_solve()  # the new seed shown
            settle(app)
            tab_threads: list[str] = []
            tab = FakeTab(tab_threads)
            app.downloads.on_share(SimpleNamespace(client=tab))  # the button's label while recording
            app.downloads.on_export(SimpleNamespace(client=tab))  # the notification
            settle(app)
        finally:
            interface.queue_message = send
        assert len(tab.files) == 3, tab.files  # the page, the GIF and the PNG: the clicks did their work
        written = {name for _, updates in writes for name in updates}
        assert {"value", "options", "disabled", "label"} <= written, written
        elsewhere = [(thread, updates) for thread, updates in writes if thread != LOOP_THREAD]
        assert not elsewhere, elsewhere[:5]
        assert tab_threads and set(tab_threads) == {LOOP_THREAD}, tab_threads
