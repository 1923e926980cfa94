"""The `harv-jax` sub-commands, one module each: top-level command functions and ``register(app)``.

Thin typer commands: parse and validate the options (``harv_jax.cli_options``, the studies' shared
``harv_jax.study_options``, ``harv_jax.guards``), call
the library (``harv_jax.evaluation``, ``harv_jax.report``, ``harv_jax.ppo``) and write. Commands never
import each other, and no library module imports them.
"""
