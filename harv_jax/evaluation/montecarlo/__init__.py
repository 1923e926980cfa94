"""The Monte Carlo (``harv-jax mc``): the shared inputs (``inputs``) and the disturbances they carry
(``disturbances``), the vectorized rollout (``rollout``), the study that runs and writes it (``study``),
and run-by-run comparisons (``paired``)."""
