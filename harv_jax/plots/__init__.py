"""Figures (matplotlib, Agg): time histories, Monte Carlo bands, envelope maps, training curves."""
