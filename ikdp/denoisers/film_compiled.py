"""The planar FiLM denoiser's step as compiled C (film_kernel.c), built on first use, torch as the fallback.

Why: one target's solve runs the denoiser 80 times on 16 rows. In torch each call is some
forty ops of a few microseconds' fixed cost each; their arithmetic is a fifth of that. The C
function does the whole call in one go (docs/BENCHMARKS.md has the times).

The kernel is compiled once per machine with the system's C compiler (`cc`, or $CC) into
ikdp's cache folder ($IKDP_CACHE, else $XDG_CACHE_HOME/ikdp, else ~/.cache/ikdp), keyed by
the source, the flags, the compiler and the CPU (it is built with -march=native), and
written atomically. No compiler, a failed build, IKDP_COMPILED=0, a GPU tensor or float64:
`compiled_workspace` returns None and the torch path runs, with the same results to float
rounding (tests/test_film_compiled.py compares them).
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import platform
import shutil
import subprocess
import tempfile
import threading
from pathlib import Path

import torch

SOURCE = Path(__file__).with_name("film_kernel.c")
# -ffast-math lets the compiler vectorise expf (SiLU, through glibc's vector maths) and reassociate the
# sums: results differ from torch's at float rounding, as torch's own kernels differ between machines
FLAGS = ("-O3", "-march=native", "-ffast-math", "-shared", "-fPIC", "-std=c99")

_lock = threading.Lock()
_library: ctypes.CDLL | None = None
_tried = False


def cache_folder() -> Path:
    if os.environ.get("IKDP_CACHE"):
        return Path(os.environ["IKDP_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "ikdp"


def _compiler() -> str | None:
    return shutil.which(os.environ.get("CC", "cc")) or shutil.which("gcc") or shutil.which("clang")


def _cpu_name() -> str:
    """The CPU's model and instruction-set flags: a library built with -march=native runs only where they match."""
    try:
        lines = Path("/proc/cpuinfo").read_text().splitlines()
    except OSError:
        return platform.processor()
    first = {}
    for line in lines:
        name = line.split(":", 1)[0].strip()
        if name in ("model name", "flags") and name not in first:
            first[name] = line
    return "\n".join(first.values()) or platform.processor()


def _build(compiler: str) -> Path:
    version = subprocess.run([compiler, "--version"], capture_output=True, text=True, timeout=30).stdout
    key = hashlib.sha256(
        "\0".join((SOURCE.read_text(), " ".join(FLAGS), version, _cpu_name(), platform.machine())).encode()
    ).hexdigest()[:16]
    library = cache_folder() / f"film_kernel-{key}.so"
    if library.exists():
        return library
    library.parent.mkdir(parents=True, exist_ok=True)
    # build beside the target and rename: a concurrent process or a kill never leaves half a library
    handle, temporary = tempfile.mkstemp(prefix=".film_kernel-", suffix=".so", dir=library.parent)
    os.close(handle)
    try:
        subprocess.run(
            [compiler, *FLAGS, str(SOURCE), "-o", temporary, "-lm"], check=True, capture_output=True, timeout=120
        )
        os.replace(temporary, library)
    finally:
        if os.path.exists(temporary):
            os.unlink(temporary)
    return library


def load_kernel() -> ctypes.CDLL | None:
    """The compiled kernel, built on the first call; None where it cannot be (then never tried again)."""
    global _library, _tried
    with _lock:
        if _tried:
            return _library
        _tried = True
        if os.environ.get("IKDP_COMPILED", "1") == "0":
            return None
        compiler = _compiler()
        if compiler is None:
            return None
        try:
            library = ctypes.CDLL(str(_build(compiler)))
        except (OSError, subprocess.SubprocessError):
            return None
        function = library.ikdp_film_denoise
        pointer, long = ctypes.c_void_p, ctypes.c_long
        function.argtypes = [ctypes.POINTER(FilmStep), pointer, pointer, long, pointer, long, long]
        function.restype = ctypes.c_int
        library.ikdp_film_chunk_rows.argtypes, library.ikdp_film_chunk_rows.restype = [], ctypes.c_int
        _library = library
        return library


class FilmStep(ctypes.Structure):
    """film_kernel.c's FilmStep: what stays the same from call to call, converted once, not per call."""

    _fields_ = [
        *((name, ctypes.c_int) for name in ("rows", "links", "hidden", "blocks")),
        ("lengths", ctypes.c_void_p),
        ("damping_squared", ctypes.c_float),
        *((name, ctypes.c_void_p) for name in ("w_in", "b_in", "w_blocks", "b_blocks", "w_out", "b_out")),
        ("scratch", ctypes.c_void_p),
        ("clean", ctypes.c_void_p),
    ]


class CompiledFiLMWorkspace:
    """`FiLMDenoiser.denoise` on M rows through film_kernel.c; the interface of film.FiLMWorkspace."""

    def __init__(self, denoiser, rows: int, library: ctypes.CDLL):
        representation, hidden = denoiser.representation, denoiser.config.hidden
        links, blocks = representation.num_links, len(denoiser.blocks)
        self.function = library.ikdp_film_denoise
        contiguous = lambda tensor: tensor.detach().to(torch.float32).contiguous()  # noqa: E731
        # the weights transposed once, kept alive here: the kernel reads them by address
        self.lengths = contiguous(denoiser.lengths)
        self.w_in, self.b_in = contiguous(denoiser.input.weight.t()), contiguous(denoiser.input.bias)
        self.w_blocks = contiguous(torch.stack([block.weight.t() for block in denoiser.blocks]))
        self.b_blocks = contiguous(torch.stack([block.bias for block in denoiser.blocks]))
        self.w_out, self.b_out = contiguous(denoiser.output.weight.t()), contiguous(denoiser.output.bias)
        num_features = denoiser.input.in_features
        chunk = min(rows, library.ikdp_film_chunk_rows())  # the kernel takes rows through the layers in chunks
        self.scratch = torch.empty(chunk * (num_features + 3 * hidden + 3 * links), dtype=torch.float32)
        self.clean = torch.empty((rows, representation.dim), dtype=torch.float32)
        # the arguments that do not change between calls, converted once: a call then passes seven
        address = lambda tensor: tensor.data_ptr()  # noqa: E731
        self.step = FilmStep(
            rows, links, hidden, blocks, address(self.lengths), float(denoiser.damping_squared),
            *(address(tensor) for tensor in (self.w_in, self.b_in, self.w_blocks, self.b_blocks)),
            address(self.w_out), address(self.b_out), address(self.scratch), address(self.clean),
        )  # fmt: skip
        self.step_pointer = ctypes.byref(self.step)

    # the sampling loop may pass one target and one condition per target, (B, ...), for M = B K rows
    accepts_per_target_conditions = True

    def denoise(self, x: torch.Tensor, target: torch.Tensor, film: torch.Tensor) -> torch.Tensor:
        """The plain `FiLMDenoiser.denoise`; returns the `clean` buffer (M, D), overwritten by the next call.

        `target` and `film` hold one row for all M rows, one per row, or one per group of M / B
        consecutive rows (the K samples of each of B targets): the kernel reads a group's row
        for each of its rows instead of the caller copying it K times.
        """
        rows = x.shape[0]
        counts = {count for count in (target.shape[0], film.shape[0]) if count > 1}
        if len(counts) > 1 or (counts and rows % next(iter(counts))):
            raise ValueError(
                f"compiled FiLM step: {rows} rows cannot share {target.shape[0]} targets and {film.shape[0]} conditions"
            )
        rows_per_condition = rows // counts.pop() if counts else 1
        if not x.is_contiguous():
            x = x.contiguous()
        if target.stride(-1) != 1:
            target = target.contiguous()
        if not film.is_contiguous() and not film[0].is_contiguous():  # rows may repeat (stride 0), not scatter
            film = film.contiguous()
        # one target or one condition for every row: stride 0 reads the same row again
        target_stride = target.stride(0) if target.shape[0] > 1 else 0
        film_stride = film.stride(0) if film.shape[0] > 1 else 0
        self.function(
            self.step_pointer, x.data_ptr(), target.data_ptr(), target_stride, film.data_ptr(), film_stride,
            rows_per_condition,
        )  # fmt: skip
        return self.clean


def compiled_workspace(denoiser, rows: int, like: torch.Tensor) -> CompiledFiLMWorkspace | None:
    """A compiled workspace for float32 CPU tensors when the kernel builds here, else None (torch's)."""
    if like.device.type != "cpu" or like.dtype != torch.float32:
        return None
    if rows > 256 and torch.get_num_threads() > 1:  # the kernel runs on one thread; torch spreads large batches
        return None
    library = load_kernel()
    return CompiledFiLMWorkspace(denoiser, rows, library) if library is not None else None
