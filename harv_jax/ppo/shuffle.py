"""``jax.random.permutation(key, n)``, bit for bit, with a cheaper sort.

JAX shuffles by sorting the indices on random 32-bit keys, ``ceil(3 ln n / ln(2^32 - 1))`` rounds of a stable
key-value sort (two rounds for a PPO batch of 32,768). XLA's CPU backend runs a key-value sort through a
comparator callback, while a single-operand sort of a primitive type takes a fast path. Packing each key
with the element's position into one uint64 (``key << 32 | position``) makes the keys distinct, so a plain
ascending sort gives the stable key order, and the low 32 bits carry the permutation. Measured on the 2-core
AVX-512 EPYC, n = 32,768: 1.3 ms against 6.7 ms per round (``tests/test_shuffle.py`` checks equality).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

_LOW_32 = 0xFFFFFFFF


def num_rounds(n: int) -> int:
    """Sort rounds of ``jax.random.permutation`` for ``n`` elements (its static stop criterion)."""
    return int(np.ceil(3 * np.log(max(1, n)) / np.log(np.iinfo(np.uint32).max)))


def permutation(key: jax.Array, n: int) -> jax.Array:
    """A random permutation of ``arange(n)`` [n] int32, equal to ``jax.random.permutation(key, n)``.

    Args:
        key: PRNG key (typed or raw uint32).
        n: static number of elements (n < 2**31).

    Returns:
        [n] int32 permutation.
    """
    if not 0 <= n < 2**31:
        raise ValueError(f"n = {n} is out of range: permutations of 0 <= n < 2**31 elements")
    perm = jnp.arange(n, dtype=jnp.int32)
    for _ in range(num_rounds(n)):
        key, subkey = jax.random.split(key)
        sort_keys = jax.random.bits(subkey, (n,), jnp.uint32)
        with jax.enable_x64(True):
            packed = (sort_keys.astype(jnp.uint64) << 32) | jnp.arange(n, dtype=jnp.uint64)
            order = (jax.lax.sort(packed) & _LOW_32).astype(jnp.int32)
        perm = perm[order]
    return perm
