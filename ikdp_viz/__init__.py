"""ikdp_viz: the interactive browser viewer of IKDP's reverse diffusion (viser).

    python -m ikdp_viz --ckpt ikdp_n4      # or: ikdp-viz; a shipped model's name or a checkpoint's path

`scene` turns a solve into drawable arrays and never imports viser; `app` is the
viser layer; `__main__` the command line. Importing the package does nothing.
"""
