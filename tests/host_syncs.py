"""A recorder of what a CUDA graph cannot capture, run on a CPU: the captured code must make none of it."""

import torch
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
