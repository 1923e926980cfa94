"""Benchmarks of harv_jax (run as scripts; numpy_harv is importable by tests)."""
