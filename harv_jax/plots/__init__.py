"""Figures (matplotlib, Agg), written to PNG; no computation beyond what a figure needs.

- ``time_histories``: the paper's four-figure layout of one or more runs (``plot_time_histories``);
- ``flight``: one flight's hybrid authority/command split and sliding variables;
- ``mc``: Monte Carlo percentile bands (and their CSV) and terminal-error histograms;
- ``maps``: recovery envelope maps (outcome and recovery time per grid point);
- ``training``: training curves.
"""
