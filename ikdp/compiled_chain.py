"""SmallRefine's refinement loop and the denoiser's error-and-step feature as compiled C (chain_refine_kernel.c).

Why: one target's K = 16 poses make arrays of a few hundred numbers, and NumPy's loop (ikdp/small_refine.py) spends
its time on the fixed cost of some sixty operations a step: on one Xeon thread a Panda solve's refinement took a
third of its 2 ms and the network's kinematic feature a seventh. The C file does the same arithmetic pose by pose in
one call. It is built like the planar FiLM kernel (ikdp/denoisers/film_compiled.py: the system's C compiler, on
first use, into ikdp's cache folder, for this CPU where the compiler can); without it (IKDP_COMPILED=0, no
compiler, a failed build) NumPy's loop runs, the same numbers to rounding (tests/test_compiled_chain.py), and the
log says so once.
"""

from __future__ import annotations

import ctypes
import logging
import threading
from pathlib import Path

import numpy as np

SOURCE = Path(__file__).with_name("chain_refine_kernel.c")
MAX_JOINTS = 64  # the kernel's: a longer chain takes NumPy's loop

logger = logging.getLogger(__name__)
_lock = threading.Lock()
_library: ctypes.CDLL | None = None
_tried = False


class ChainConstants(ctypes.Structure):
    """chain_refine_kernel.c's Chain: the chain's constants by address, set once per chain."""

    _fields_ = [
        ("joints", ctypes.c_int),
        ("pose_targets", ctypes.c_int),
        *(
            (name, ctypes.c_void_p)
            for name in ("fixed", "cosine", "sine", "slide", "prismatic", "revolute", "continuous", "limited")
        ),
        *((name, ctypes.c_void_p) for name in ("lower", "upper", "end")),
    ]


def open_library(path: Path) -> ctypes.CDLL:
    library = ctypes.CDLL(str(path))
    pointer, integer, real = ctypes.c_void_p, ctypes.c_int, ctypes.c_double
    step = library.ikdp_chain_error_and_step
    step.argtypes = [ctypes.POINTER(ChainConstants), integer, pointer, pointer, real, pointer, pointer]
    step.restype = integer
    refine = library.ikdp_chain_refine
    refine.argtypes = [
        ctypes.POINTER(ChainConstants), integer, pointer, pointer, integer, real, real, real, integer, real, real,
        integer, integer, pointer,
    ]  # fmt: skip
    refine.restype = integer
    return library


def load_kernel() -> ctypes.CDLL | None:
    """The compiled kernel, built on the first call; None where it cannot be (then never tried again)."""
    global _library, _tried
    with _lock:
        if not _tried:
            _tried = True
            from ikdp.denoisers import film_compiled  # the build machinery the two C files share

            _library, reason = film_compiled.built_library(SOURCE, open_library)
            if _library is None:
                level = logging.INFO if reason == "IKDP_COMPILED=0" else logging.WARNING
                logger.log(level, "ikdp: a few poses' refinement runs in NumPy (%s), several times slower", reason)
        return _library


class CompiledChain:
    """One chain's constants for the kernel (`SmallRefine`'s NumPy arrays, kept alive here: read by address)."""

    def __init__(self, refine, library: ctypes.CDLL):
        def floats(array):
            return None if array is None else np.ascontiguousarray(array, dtype=np.float64)

        def flags(array):
            return None if array is None else np.ascontiguousarray(array, dtype=np.uint8).reshape(-1)

        self.arrays = {
            "fixed": floats(refine.fixed),
            "cosine": floats(refine.cosine),
            "sine": floats(refine.sine),
            "slide": floats(refine.slide),
            "prismatic": floats(refine.prismatic),
            "revolute": flags(refine.revolute),
            "continuous": flags(refine.continuous),
            "limited": flags(refine.limited),
            "lower": floats(refine.lower),
            "upper": floats(refine.upper),
            "end": floats(refine.end),
        }
        address = lambda array: None if array is None else array.ctypes.data  # noqa: E731
        self.constants = ChainConstants(
            len(self.arrays["lower"]), int(refine.pose_targets), *(address(array) for array in self.arrays.values())
        )
        self.pointer = ctypes.byref(self.constants)
        self.num_joints = len(self.arrays["lower"])
        self.error_dim = 6 if refine.pose_targets else 3
        self.library = library

    def error_and_step(self, joints: np.ndarray, goals: np.ndarray, damping_squared: float):
        """joints (N, J), goals (N, target_dim), float64 -> the task error (N, E) and the damped least-squares step
        (N, J): `SmallRefine.error_and_step`'s arrays."""
        joints, goals = np.ascontiguousarray(joints), np.ascontiguousarray(goals)
        error = np.empty((len(joints), self.error_dim))
        step = np.empty_like(joints)
        self.library.ikdp_chain_error_and_step(
            self.pointer, len(joints), joints.ctypes.data, goals.ctypes.data, damping_squared, error.ctypes.data,
            step.ctypes.data,
        )  # fmt: skip
        return error, step

    def refine(
        self,
        joints: np.ndarray,
        goals: np.ndarray,
        steps: int,
        damping_squared: float,
        limits: tuple[float, float],
        until_within: tuple[int, float, float] | None,
        scored: bool,
        round_float32: bool,
    ) -> tuple[np.ndarray, np.ndarray]:
        """`SmallRefine.refine_scored`'s loop on joints (N, J), goals (N, target_dim), float64 -> the refined joints
        (a new array) and the scores (3, N) float32: position errors, rotation angles, first position errors."""
        joints = np.array(joints, dtype=np.float64, order="C")  # written in place: never the caller's memory
        goals = np.ascontiguousarray(goals)
        scores = np.empty((3, len(joints)), dtype=np.float32)
        per_target, position_tolerance, rotation_tolerance = until_within if until_within is not None else (0, 0, 0)
        status = self.library.ikdp_chain_refine(
            self.pointer, len(joints), joints.ctypes.data, goals.ctypes.data, steps, damping_squared, limits[0],
            limits[-1], per_target, position_tolerance, rotation_tolerance, scored, round_float32, scores.ctypes.data,
        )  # fmt: skip
        if status != 0:
            raise MemoryError(f"the compiled refinement could not allocate its buffers for {len(joints)} poses")
        return joints, scores


def compiled_chain(refine) -> CompiledChain | None:
    """The kernel for `SmallRefine`'s chain when it builds here and the chain fits it, else None (NumPy's loop)."""
    if len(refine.lower) > MAX_JOINTS:
        return None
    library = load_kernel()
    return None if library is None else CompiledChain(refine, library)
