"""The `harv-jax` sub-commands, one module each with ``register(app)``.

Thin typer commands: parse and validate the options (``harv_jax.cli_options``, ``harv_jax.guards``), call
the library (``harv_jax.evaluation``, ``harv_jax.report``, ``harv_jax.ppo``) and write. Commands never
import each other, and no library module imports them.
"""
