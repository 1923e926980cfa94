"""The trainer's shuffle equals ``jax.random.permutation`` bit for bit (harv_jax.ppo.shuffle)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from harv_jax.ppo.shuffle import num_rounds, permutation


@pytest.mark.parametrize("n", [0, 1, 2, 7, 1000, 4097, 32768])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_equals_jax_permutation(n: int, seed: int) -> None:
    key = jax.random.key(seed)
    expected = np.asarray(jax.random.permutation(key, n))
    got = np.asarray(jax.jit(permutation, static_argnums=1)(key, n))
    assert got.dtype == expected.dtype == np.int32
    np.testing.assert_array_equal(got, expected)


@pytest.mark.slow
def test_three_rounds_and_raw_keys() -> None:
    n = 2_700_000  # above 2.6M elements jax sorts three times
    assert [num_rounds(m) for m in (1, 1000, 32768, n)] == [0, 1, 2, 3]
    key = jax.random.PRNGKey(7)  # raw uint32 key
    np.testing.assert_array_equal(np.asarray(permutation(key, n)), np.asarray(jax.random.permutation(key, n)))


def test_under_vmap_and_as_a_permutation() -> None:
    keys = jax.random.split(jax.random.key(5), 4)
    got = jax.jit(jax.vmap(lambda k: permutation(k, 4096)))(keys)
    expected = jax.vmap(lambda k: jax.random.permutation(k, 4096))(keys)
    np.testing.assert_array_equal(np.asarray(got), np.asarray(expected))
    for row in np.asarray(got):
        np.testing.assert_array_equal(np.sort(row), np.arange(4096))
    assert not np.array_equal(np.asarray(got[0]), np.asarray(got[1]))


def test_ties_keep_the_stable_order() -> None:
    """Collisions of the 32-bit keys are where a plain sort could differ from the stable key-value sort."""
    n = 200_000  # ~4.7 expected key collisions per round
    key = jax.random.key(11)
    bits = jax.random.bits(jax.random.split(key)[1], (n,), jnp.uint32)
    assert len(np.unique(np.asarray(bits))) < n  # this draw has collisions
    np.testing.assert_array_equal(np.asarray(permutation(key, n)), np.asarray(jax.random.permutation(key, n)))


@pytest.mark.parametrize("n", [-1, 2**31])
def test_rejects_bad_size(n: int) -> None:
    with pytest.raises(ValueError, match=r"n = .* is out of range"):
        permutation(jax.random.key(0), n)
