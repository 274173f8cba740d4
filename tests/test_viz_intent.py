"""The drawing loop's intent (ikdp_viz/intent.py): what callbacks ask, merged until the loop takes it."""

import threading

import numpy as np

from ikdp_viz.intent import Asked, StateAsked, TargetMove


def loop_recording(taken: list, gate: threading.Event | None = None) -> Asked:
    def apply(intent):
        if gate is not None:
            gate.wait(10)
        if not intent.empty():
            taken.append(intent)

    return Asked(apply, wait=lambda: None, failed=lambda: None)


def test_asks_before_the_loop_looks_merge_newest_first_and_deltas_add():
    taken, gate = [], threading.Event()
    asked = loop_recording(taken, gate)
    asked.ask(redraw=True)  # the loop takes this one and waits at the gate
    for _ in range(50):
        if asked._intent.empty():
            break
        threading.Event().wait(0.01)
    first, second = np.array([1.0, 0.0]), np.array([0.0, 2.0])
    asked.ask(target=TargetMove(first, False, move_gizmo=True, force=False), solve=(1.0, True))
    asked.ask(target=TargetMove(second, False, move_gizmo=False, force=True), solve=(2.0, False))
    asked.ask(state=StateAsked(delta=1))
    asked.ask(state=StateAsked(delta=1), toggle_play=True)
    asked.ask(toggle_play=True, prior=np.zeros((3, 5, 2)), changed=["samples"])
    asked.ask(changed=["sampler"])
    gate.set()
    assert asked.flush(10)
    merged = taken[-1]
    assert np.array_equal(merged.target.target, second) and merged.solve == (2.0, False)
    assert merged.target.move_gizmo and merged.target.force  # the gizmo follows if any move asked it
    assert merged.state == StateAsked(delta=2) and not merged.toggle_play  # two toggles: back as it was
    assert merged.prior.shape == (3, 5, 2) and merged.changed == ["samples", "sampler"]
    asked.close()


def test_an_intent_holding_arrays_is_taken_while_the_loop_is_busy():
    taken, gate = [], threading.Event()
    asked = loop_recording(taken, gate)
    asked.ask(redraw=True)
    asked.ask(prior=np.zeros((2, 3, 2)), replay=np.array([0.5, 0.5]))  # asked while the loop applies the first
    gate.set()
    assert asked.flush(10) and asked.idle
    assert any(intent.prior is not None and intent.replay is not None for intent in taken)
    asked.close()
