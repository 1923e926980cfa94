"""Device placement of the training state: the env-axis mesh, its shardings, and host -> device puts.

The env axis of the env state, observations and episode accumulators is sharded over a 1-D mesh
``("envs",)``; parameters, optimizer state and normaliser are replicated. Minibatches are constrained to be
sharded along their batch axis, so each device computes the loss on its slice and XLA's partitioner inserts
the all-reduce that averages gradients. The algorithm does not depend on the device count (same PRNG
streams, global permutation), so 2-device and 1-device training agree to floating-point reduction order
(tested).
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding
from jax.sharding import PartitionSpec as P

#: Name of the mesh axis the envs are sharded over.
ENV_AXIS = "envs"


def default_devices() -> list[jax.Device]:
    """Devices to shard envs over by default: all of them on accelerators, one on CPU.

    On CPU one device already uses every core (XLA's intra-op thread pool), so CPU sharding is opt-in:
    pass ``devices`` explicitly.
    """
    devices = jax.devices()
    return devices[:1] if devices[0].platform == "cpu" else devices


def env_mesh(devices: list[jax.Device]) -> Mesh:
    """The 1-D mesh ``("envs",)`` over ``devices``."""
    return Mesh(np.asarray(devices), (ENV_AXIS,))


def batch_sharding(mesh: Mesh) -> NamedSharding:
    """Leading (batch) axis split over the env axis."""
    return NamedSharding(mesh, P(ENV_AXIS))


def replicated(mesh: Mesh) -> NamedSharding:
    """Every device holds the whole array."""
    return NamedSharding(mesh, P())


def env_sharded(mesh: Mesh) -> NamedSharding:
    """Per-seed env-axis leaves [S, N, ...]: axis 1 split over the devices."""
    return NamedSharding(mesh, P(None, ENV_AXIS))


def put_global(x: Any, sharding: jax.sharding.Sharding) -> jax.Array:
    """A host value (numpy or key array) as a jax.Array with ``sharding``, also when the sharding spans
    several processes (``jax.device_put`` accepts only process-local shardings there): each process builds
    its own shards from the same host value."""
    if jnp.issubdtype(getattr(x, "dtype", np.float32), jax.dtypes.prng_key):
        data = np.asarray(jax.random.key_data(x))
        arr = jax.make_array_from_callback(data.shape, sharding, lambda idx: data[idx])
        return jax.random.wrap_key_data(arr, impl=jax.random.key_impl(x))
    x = np.asarray(x)
    return jax.make_array_from_callback(x.shape, sharding, lambda idx: x[idx])
