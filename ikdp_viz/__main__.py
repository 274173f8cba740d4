"""Command line of the IKDP viewer: start a viser server and print the URL to open.

    python -m ikdp_viz                                   # the shipped checkpoints/ikdp_n4.pt
    python -m ikdp_viz --ckpt checkpoints/ikdp_n8.pt --port 8081
    python -m ikdp_viz --host 0.0.0.0                    # let other machines connect

A checkpoint that cannot be used is a one-line error and exit status 2;
Ctrl-C stops the server cleanly.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import io
import signal
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from ikdp_viz import DEFAULT_CHECKPOINT, DEFAULT_CHECKPOINT_DIR


@dataclass(frozen=True)
class VizConfig:
    ckpt: str = field(
        default="", metadata={"help": f"checkpoint to open (default: the shipped {DEFAULT_CHECKPOINT.name})"}
    )
    host: str = field(
        default="127.0.0.1", metadata={"help": "address to listen on; 0.0.0.0 lets other machines connect"}
    )
    port: int = field(default=8080, metadata={"help": "port to listen on; if taken, the next free one"})
    device: str = field(default="cpu", metadata={"help": "torch device the model runs on: cpu, cuda, cuda:1, ..."})


def parse_config(argv: list[str] | None = None) -> VizConfig:
    parser = argparse.ArgumentParser(
        prog="ikdp-viz",
        description="Interactive browser view of IKDP's reverse diffusion: drag the target, watch the arm denoise.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    for option in dataclasses.fields(VizConfig):
        parser.add_argument(
            f"--{option.name}", type=type(option.default), default=option.default, help=option.metadata["help"]
        )
    return VizConfig(**vars(parser.parse_args(argv)))


def fail(message: str) -> None:
    print(f"ikdp-viz: error: {message}", file=sys.stderr)
    raise SystemExit(2)


def load_solver(path: Path, device: str):
    import ikdp  # imported here: torch is slow to import and `--help` needs none of it

    try:
        return ikdp.load(path, device=device)
    except ikdp.CheckpointError as error:
        fail(str(error))
    except OSError as error:
        fail(f"{path}: cannot read it ({error.strerror or error})")
    except (RuntimeError, AssertionError) as error:  # torch's answer to an unknown or absent device
        reason = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
        fail(f"--device {device}: {reason}")


def main(argv: list[str] | None = None) -> None:
    config = parse_config(argv)
    signal.signal(signal.SIGTERM, signal.default_int_handler)  # a kill stops as cleanly as Ctrl-C
    server = app = None
    try:
        path = Path(config.ckpt) if config.ckpt else DEFAULT_CHECKPOINT
        solver = load_solver(path, config.device)

        import torch
        import viser

        from ikdp_viz.app import VizApp, list_checkpoints

        torch.set_num_threads(1)  # one small solve at a time: more threads only spin against each other
        with contextlib.redirect_stdout(io.StringIO()):  # viser's own banner; the URL is printed below
            server = viser.ViserServer(host=config.host, port=config.port, verbose=False)
        app = VizApp(
            server,
            solver,
            checkpoints=list_checkpoints(DEFAULT_CHECKPOINT_DIR, path),
            checkpoint_folder=DEFAULT_CHECKPOINT_DIR,
        )
        port = server.get_port()
        shown_host = "localhost" if config.host in ("0.0.0.0", "::", "") else config.host
        print(f"ikdp-viz: open http://{shown_host}:{port}", flush=True)
        details = f"model {path} (N={solver.num_links}, T={solver.timesteps}); Ctrl-C to stop"
        if port != config.port:
            details = f"port {config.port} was taken, using {port}; " + details
        if config.host in ("0.0.0.0", "::"):
            details = "listening on all interfaces; " + details
        print(f"ikdp-viz: {details}", flush=True)
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        pass
    finally:
        if app is not None:
            app.close()
        if server is not None:
            server.stop()
    print("ikdp-viz: stopped", file=sys.stderr, flush=True)


if __name__ == "__main__":
    main()
