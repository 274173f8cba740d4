"""Baselines IKDP is measured against: classical solvers and learned regressors."""
