"""No compiled training program holds a batched LAPACK factorization.

On the CPU, jaxlib splits a batched factorization into tasks on XLA's intra-op thread pool and blocks the
calling pool worker until they finish; when independent ones run at once on every worker, the program never
completes (``experiments/train_stress/README.md``). The trainer therefore initialises the networks of its
seeds one after the other. These tests read the lowered programs, so they fail if a batched QR comes back.
"""

from __future__ import annotations

import dataclasses
import re

import jax
import numpy as np
from test_train import CFG, TOY_PARAMS, ToyEnv

from harv_jax.ppo.networks import make_ppo_networks
from harv_jax.ppo.train import make_train, seed_keys

#: A LAPACK custom call and its number of batch dimensions, in StableHLO text.
LAPACK_CALL = re.compile(r"custom_call @(lapack_\w+)\([^)]*\) \{[^\n]*?num_batch_dims = \"(\d+)\"")


def _lapack_calls(text: str) -> list[tuple[str, int]]:
    return [(name, int(n)) for name, n in LAPACK_CALL.findall(text)]


def test_the_pattern_sees_a_batched_qr():
    """The check itself: a vmapped orthogonal init lowers to batched QR calls."""
    nets = make_ppo_networks(4, 3, (64, 64), -0.5)
    text = jax.jit(jax.vmap(nets.init)).lower(jax.random.split(jax.random.key(0), 3)).as_text()
    calls = _lapack_calls(text)
    assert calls and all(n == 1 for _, n in calls), calls


def test_trainer_init_factorizes_one_matrix_at_a_time():
    cfg = dataclasses.replace(CFG, num_seeds=3, hidden_sizes=(64, 64))
    trainer = make_train(ToyEnv(), cfg, TOY_PARAMS)
    text = trainer.init.lower(seed_keys(jax.random.key(0), 3), TOY_PARAMS).as_text()
    calls = _lapack_calls(text)
    assert calls, "no QR found: the orthogonal init changed; update this test"
    assert all(n == 0 for _, n in calls), calls


def test_init_seeds_equals_a_vmap_bit_for_bit():
    nets = make_ppo_networks(14, 3, (64, 64), -0.5)
    keys = jax.random.split(jax.random.key(3), 3)
    a = jax.vmap(nets.init)(keys)  # op by op, outside jit: one QR at a time
    b = jax.jit(nets.init_seeds)(keys)
    for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
