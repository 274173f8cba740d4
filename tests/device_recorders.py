"""Recorders, run on a CPU, of what would go wrong on a GPU: what a CUDA graph cannot capture (a host sync, a copy
from the host) and a random draw made off its generator's device."""

import torch
from torch.overrides import TorchFunctionMode
from torch.utils._python_dispatch import TorchDispatchMode

HOST_SYNCS = {"aten::_local_scalar_dense", "aten::nonzero", "aten::masked_select", "aten::is_nonzero", "aten::equal"}


class HostSyncRecorder(TorchDispatchMode):
    """Records the ops that would wait for a GPU or copy from the host, which a CUDA graph cannot capture:
    a tensor read into Python, a shape that depends on data, a tensor made from host data (`torch.tensor`)."""

    def __init__(self):
        super().__init__()
        self.found: list[str] = []

    def __torch_dispatch__(self, func, types, args=(), kwargs=None):
        name = func._schema.name
        masks = name in ("aten::index", "aten::index_put_") and any(
            isinstance(index, torch.Tensor) and index.dtype == torch.bool for index in args[1] if index is not None
        )
        if name in HOST_SYNCS or name == "aten::lift_fresh" or masks:
            self.found.append(name)
        return func(*args, **(kwargs or {}))


class HostCopyRecorder(TorchFunctionMode):
    """Records each `.to(...)` that would copy a tensor from the host inside a capture: on a CPU every copy is a
    no-op, so it is found by origin instead. A tensor made before the recording (a constant kept on the CPU)
    moved by `.to` is reported, unless it is one of `own` (the model's parameters and buffers, on the device
    already); tensors made while recording may move freely (they are on the device)."""

    def __init__(self, own=()):
        super().__init__()
        self.own = {id(tensor) for tensor in own}
        self.made: list[torch.Tensor] = []  # kept alive so that their ids are not reused
        self.made_ids: set[int] = set()
        self.found: list[str] = []

    def __torch_function__(self, func, types, args=(), kwargs=None):
        kwargs = kwargs or {}
        if func in (torch.Tensor.to, torch.Tensor.cuda) and isinstance(args[0], torch.Tensor):
            source = args[0]
            if id(source) not in self.made_ids and id(source) not in self.own:
                self.found.append(f"{tuple(source.shape)} {source.dtype}")
        result = func(*args, **kwargs)
        for tensor in result if isinstance(result, (tuple, list)) else (result,):
            if isinstance(tensor, torch.Tensor):
                self.made.append(tensor)
                self.made_ids.add(id(tensor))
        return result


class RandomDraws(TorchFunctionMode):
    """Every random draw, the device it names and the generator it takes: a draw that names no device is made on
    the CPU, which with a CUDA generator is an error, and with data on a GPU a host copy per call."""

    def __init__(self):
        super().__init__()
        self.draws: list[tuple[str, object, torch.Generator | None]] = []

    def __torch_function__(self, func, types, args=(), kwargs=None):
        kwargs = kwargs or {}
        if getattr(func, "__name__", "") in ("rand", "randn", "randint", "normal", "multinomial"):
            out = kwargs.get("out")  # a draw into a buffer lands on the buffer's device
            device = out.device if isinstance(out, torch.Tensor) else kwargs.get("device")
            self.draws.append((func.__name__, device, kwargs.get("generator")))
        return func(*args, **kwargs)

    def off_device(self, generator: torch.Generator) -> list[str]:
        """The draws from `generator` made off its device."""
        return [
            name
            for name, device, drawn_from in self.draws
            if drawn_from is generator and (device is None or torch.device(device) != generator.device)
        ]
