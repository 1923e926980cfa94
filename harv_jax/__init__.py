"""harv_jax: vectorized F-18/HARV flight model, controllers and RL training in JAX."""

__version__ = "0.1.0"
