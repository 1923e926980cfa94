"""Recovery envelope maps (``harv-jax envelope``): the outcome over a grid of initial conditions (``grid``)
and the study that runs and writes it (``study``)."""
