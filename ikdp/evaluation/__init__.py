"""Evaluation of IKDP beside its baselines: metrics, fidelity (MMD), tables and figures.

`python -m ikdp.evaluate` runs it all; the modules here are the pieces, each one idea.
"""
