"""The planar FiLM denoiser's step as compiled C (film_kernel.c), built on first use, torch as the fallback.

Why: one target's solve runs the denoiser 80 times on 16 rows. In torch each call is some
forty ops of a few microseconds' fixed cost each; their arithmetic is a fifth of that. The C
function does the whole call in one go: at 16 rows, 3 times faster than the torch workspace and
than torch.compile's best; at 16,000 rows, 2 times (benchmarks/film_step.py measures them).

The kernel is compiled once per machine with the system's C compiler ($CC when set, else the
first of cc, gcc, clang, cl) into ikdp's cache folder ($IKDP_CACHE, else $XDG_CACHE_HOME/ikdp,
else ~/.cache/ikdp), keyed by the source, the flags, the compiler and the CPU, and written
atomically. It is built for this CPU (-march=native) where the compiler accepts that, else
for the compiler's default target: the source is standard C with optional vector types, so
any C compiler builds it. Without the kernel (IKDP_COMPILED=0, no compiler, a failed build)
the torch path runs, with the same results to float rounding (tests/test_film_compiled.py
compares them), and the log says so once, with the reason. A GPU tensor or float64 always
takes the torch path: the kernel is float32 on the CPU.
"""

from __future__ import annotations

import ctypes
import hashlib
import logging
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

import torch

SOURCE = Path(__file__).with_name("film_kernel.c")
# -ffast-math lets the compiler vectorise expf (SiLU, through glibc's vector maths) and reassociate the
# sums: results differ from torch's at float rounding, as torch's own kernels differ between machines
FLAGS = ("-O3", "-ffast-math", "-shared", "-fPIC", "-std=c99")
NATIVE = ("-march=native",)  # tried first; a compiler or CPU that refuses it gets the portable build
MSVC_FLAGS = ("/nologo", "/O2", "/fp:fast", "/LD")
COMPILERS = ("cc", "gcc", "clang", "cl")
SUFFIX = {"win32": ".dll", "darwin": ".dylib"}.get(sys.platform, ".so")
SLOWER = "about 3 times slower for one target"  # torch workspace / kernel: benchmarks/film_step.py

logger = logging.getLogger(__name__)
_lock = threading.Lock()
_library: ctypes.CDLL | None = None
_tried = False


def cache_folder() -> Path:
    if os.environ.get("IKDP_CACHE"):
        return Path(os.environ["IKDP_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "ikdp"


def find_compiler() -> str | None:
    """$CC when set (only it: a user who names a compiler means that one), else the first on the PATH."""
    if os.environ.get("CC"):
        return shutil.which(os.environ["CC"])
    return next((found for name in COMPILERS if (found := shutil.which(name))), None)


def is_msvc(compiler: str) -> bool:
    return Path(compiler).stem.lower() in ("cl", "clang-cl")


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


def compile_command(compiler: str, flags: tuple[str, ...], output: Path, source: Path = SOURCE) -> list[str]:
    if is_msvc(compiler):  # builds the DLL and its import library beside `output`, in the build's own folder
        return [compiler, *MSVC_FLAGS, *flags, str(source), f"/Fe{output}"]
    return [compiler, *FLAGS, *flags, str(source), "-o", str(output), "-lm"]


def build(compiler: str, flags: tuple[str, ...], source: Path = SOURCE) -> Path:
    """film_kernel.c (or another of ikdp's C files, `source`) built with `flags` beside the common ones, once: the
    cached library when it exists.

    Raises subprocess.CalledProcessError (its stderr holds the compiler's message) when the build fails.
    """
    version = subprocess.run([compiler, "--version"], capture_output=True, text=True, timeout=30)
    key = hashlib.sha256(
        "\0".join(
            (source.read_text(), " ".join(compile_command(compiler, flags, Path(), source)),
             version.stdout + version.stderr, _cpu_name(), platform.machine())
        ).encode()
    ).hexdigest()[:16]  # fmt: skip
    library = cache_folder() / f"{source.stem}-{key}{SUFFIX}"
    if library.exists():
        return library
    library.parent.mkdir(parents=True, exist_ok=True)
    # build in a folder beside the target and rename: a concurrent process or a kill never leaves half a
    # library, and what else the compiler writes (MSVC's .obj, .lib, .exp) goes with the folder
    with tempfile.TemporaryDirectory(prefix=f".{source.stem}-", dir=library.parent) as folder:
        built = Path(folder) / library.name
        subprocess.run(
            compile_command(compiler, flags, built, source), check=True, capture_output=True, text=True, timeout=120,
            cwd=folder,
        )  # fmt: skip
        os.replace(built, library)
    return library


def build_for_this_cpu(compiler: str, source: Path = SOURCE) -> Path:
    """The build for this CPU, else (the compiler refuses -march=native) the compiler's default target."""
    if not is_msvc(compiler):
        try:
            return build(compiler, NATIVE, source)
        except subprocess.CalledProcessError:
            pass
    return build(compiler, (), source)


def open_library(path: Path) -> ctypes.CDLL:
    """The built kernel with its two functions' signatures set."""
    library = ctypes.CDLL(str(path))
    function = library.ikdp_film_denoise
    pointer, size = ctypes.c_void_p, ctypes.c_ssize_t
    function.argtypes = [ctypes.POINTER(FilmStep), pointer, pointer, size, pointer, size, size]
    function.restype = ctypes.c_int
    library.ikdp_film_chunk_rows.argtypes, library.ikdp_film_chunk_rows.restype = [], ctypes.c_int
    return library


def _failure(error: Exception) -> str:
    """The first line the compiler or loader gave: enough to act on, one line in the log."""
    text = getattr(error, "stderr", None) or str(error)
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    return next((line for line in lines if "error" in line.lower()), lines[0] if lines else type(error).__name__)


def built_library(source: Path = SOURCE, opener=None) -> tuple[ctypes.CDLL | None, str]:
    """The kernel built from `source` and opened by `opener` (which sets its functions' signatures; None:
    film_kernel.c's `open_library`), or None and why not."""
    if os.environ.get("IKDP_COMPILED", "1") == "0":
        return None, "IKDP_COMPILED=0"
    compiler = find_compiler()
    if compiler is None:
        named = f"CC={os.environ['CC']!r} is not on the PATH" if os.environ.get("CC") else None
        return None, named or f"no C compiler found (looked for {', '.join(COMPILERS)}; set CC to name one)"
    try:
        return (opener or open_library)(build_for_this_cpu(compiler, source)), ""
    except subprocess.CalledProcessError as error:
        return None, f"{compiler} could not build {source.name}: {_failure(error)}"
    except (OSError, subprocess.SubprocessError, AttributeError) as error:
        return None, f"{source.name} could not be built by {compiler} or loaded: {_failure(error)}"


def load_kernel() -> ctypes.CDLL | None:
    """The compiled kernel, built on the first call; None where it cannot be (then never tried again).

    The first call that finds no kernel says why in the log, once per process.
    """
    global _library, _tried
    with _lock:
        if not _tried:
            _tried = True
            _library, reason = built_library()
            if _library is None:  # switched off by the user: only a note; otherwise the user may want to fix it
                level = logging.INFO if reason == "IKDP_COMPILED=0" else logging.WARNING
                logger.log(level, "ikdp: the planar FiLM step runs in torch (%s), %s", reason, SLOWER)
        return _library


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
        self.x_shape = (rows, representation.dim)  # the rows the workspace's buffers hold
        self.condition_shape = (blocks + 1, 2, hidden)

    # the sampling loop may pass one target and one condition per target, (B, ...), for M = B K rows
    accepts_per_target_conditions = True

    def denoise(self, x: torch.Tensor, target: torch.Tensor, film: torch.Tensor) -> torch.Tensor:
        """The plain `FiLMDenoiser.denoise`; returns the `clean` buffer (M, D), overwritten by the next call.

        `target` and `film` hold one row for all M rows, one per row, or one per group of M / B
        consecutive rows (the K samples of each of B targets): the kernel reads a group's row
        for each of its rows instead of the caller copying it K times.
        """
        self.check(x, target, film)
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

    def check(self, x: torch.Tensor, target: torch.Tensor, film: torch.Tensor) -> None:
        """The kernel reads and writes by address what this workspace was sized for: anything else is refused here.

        One expression on the way through (a call of the kernel takes some 30 us: the check stays a small part
        of it); the message is worked out only when something is wrong.
        """
        float32 = torch.float32
        if (
            x.shape == self.x_shape and target.shape[1:] == (2,) and film.shape[1:] == self.condition_shape
            and target.shape[0] > 0 and film.shape[0] > 0
            and x.dtype == float32 and target.dtype == float32 and film.dtype == float32
            and x.is_cpu and target.is_cpu and film.is_cpu
        ):  # fmt: skip
            return
        expected = {"x": self.x_shape, "target": ("B", 2), "film": ("B", *self.condition_shape)}
        for name, tensor in (("x", x), ("target", target), ("film", film)):
            if tensor.dtype != float32 or not tensor.is_cpu:
                raise ValueError(
                    f"compiled FiLM step: {name} must be float32 on the CPU, got {tensor.dtype} on {tensor.device}"
                )
            shape = expected[name]
            if (
                tensor.dim() != len(shape)
                or tensor.shape[0] == 0
                or any(size != want for size, want in zip(tensor.shape, shape, strict=True) if want != "B")
            ):
                wanted = "(" + ", ".join(map(str, shape)) + ")"
                raise ValueError(f"compiled FiLM step: {name} must have shape {wanted}, got {tuple(tensor.shape)}")


def compiled_workspace(denoiser, rows: int, like: torch.Tensor) -> CompiledFiLMWorkspace | None:
    """A compiled workspace for float32 CPU tensors when the kernel builds here, else None (torch's)."""
    if like.device.type != "cpu" or like.dtype != torch.float32:
        return None
    if rows > 256 and torch.get_num_threads() > 1:  # the kernel runs on one thread; torch spreads large batches
        return None
    library = load_kernel()
    return CompiledFiLMWorkspace(denoiser, rows, library) if library is not None else None
