"""XLA compile options shared by the tests."""

from __future__ import annotations

#: XLA's fastest compile (LLVM at -O0): for tests that run short horizons or apply a controller a few times,
#: where the compile, not the run, is the cost (~30% less compile time).
FAST_COMPILE = {"xla_backend_optimization_level": 0}
