"""Near-optimal recoveries by differentiable simulation (``harv-jax optimal``).

Owns the class of controls the optimum is searched over (``schedule``: the braking SMC fed a time-varying
reference), the smooth surrogate of recovery time (``objective``), the vmapped gradient search with its
re-simulation and improvement-only acceptance (``search``), the Monte Carlo / spin study around it
(``study``) and the demonstrations written for a learned policy (``demos``). It sits at the evaluation
layer: it flies controllers of ``harv_jax.control`` through ``harv_jax.evaluation``'s closed loop and
scoring, and no lower layer imports it.
"""
