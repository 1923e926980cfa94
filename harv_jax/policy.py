"""Trained-policy API: load a policy, act deterministically or stochastically, export it.

``load(path)`` accepts a training run folder (``<run>/policy/policy.npz``), a ``.npz`` written by
[`export_npz`][], or a training checkpoint (``ckpt_*.msgpack``; ``seed`` picks the learner). It returns a
[`Policy`][] with jitted ``deterministic(obs) -> action`` and ``stochastic(key, obs) -> action``; ``obs``
is the env observation ``[..., 11]`` in physical units (ft/s, rad, rad/s), ``action`` the normalised command
``[..., 3]`` in [-1, 1] (the env maps it affinely to [u_min, u_max] rad per surface).

Plain ``.npz`` layout (``np.load(path, allow_pickle=False)``), for use outside Python: ``obs_mean [O]``,
``obs_std [O]``: ``x = clip((obs - obs_mean) / obs_std, -10, 10)`` (``x = obs`` when
``meta["normalize_observations"]`` is false); actor layers ``policy/hidden_<i>/kernel [in, out]``,
``policy/hidden_<i>/bias [out]`` with ``h = tanh(h @ kernel + bias)``, then ``mean = h @ policy/out/kernel +
policy/out/bias``; ``policy/log_std [A]``; critic likewise under ``value/``; ``meta`` a JSON string (sizes,
config, seed, ``obs_count``). Deterministic action: ``clip(mean, -1, 1)``; stochastic: ``clip(mean +
exp(log_std) * N(0, 1), -1, 1)``.

``export_stablehlo`` writes the deterministic policy with ``jax.export`` (serialized StableHLO, symbolic
batch size, weights baked in); ``load_exported`` reads it back without the model code (both in
``harv_jax.policy_stablehlo``).
"""

from __future__ import annotations

import functools
import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import traverse_util

from harv_jax import atomic
from harv_jax.errors import UsageError
from harv_jax.guards import MAX_LAYER_WIDTH, check_npz_archive
from harv_jax.policies import DEFAULT_SHIPPED, SHIPPED, SHIPPED_PREFIX
from harv_jax.ppo import normalize as obs_norm
from harv_jax.ppo.networks import (
    PPONetworks,
    PPOParams,
    make_ppo_networks,
    postprocess,
    sample_raw_action,
)
from harv_jax.task.measurement_path import path_from_record

NPZ_FORMAT = "harv_jax.policy.npz/1"


@dataclass(frozen=True)
class Policy:
    """A loaded policy.

    Attributes:
        deterministic: jitted ``obs [..., O] -> action [..., A]`` (clip of the Gaussian mean).
        stochastic: jitted ``(key, obs [..., O]) -> action [..., A]`` (clipped Gaussian sample).
        value: jitted ``obs [..., O] -> V(obs)`` (scaled-reward units of training).
        params: actor/critic parameters.
        normalizer: observation statistics used by the policy.
        networks: the modules.
        meta: sizes, config and provenance.
    """

    deterministic: Callable[[jax.Array], jax.Array]
    stochastic: Callable[[jax.Array, jax.Array], jax.Array]
    value: Callable[[jax.Array], jax.Array]
    params: PPOParams
    normalizer: obs_norm.RunningStats
    networks: PPONetworks
    meta: dict[str, Any]


def make_policy(
    params: PPOParams,
    normalizer: obs_norm.RunningStats,
    networks: PPONetworks,
    normalize_observations: bool = True,
    meta: dict[str, Any] | None = None,
) -> Policy:
    """Wrap parameters into a [`Policy`][] (one learner: no seed axis)."""

    def prep(obs: jax.Array) -> jax.Array:
        obs = jnp.asarray(obs, jnp.float32)
        return obs_norm.normalize(normalizer, obs) if normalize_observations else obs

    def deterministic(obs: jax.Array) -> jax.Array:
        mean, _ = networks.policy(params, prep(obs))
        return postprocess(mean)

    def stochastic(key: jax.Array, obs: jax.Array) -> jax.Array:
        mean, log_std = networks.policy(params, prep(obs))
        return postprocess(sample_raw_action(key, mean, log_std))

    def value(obs: jax.Array) -> jax.Array:
        return networks.value(params, prep(obs))

    return Policy(
        deterministic=jax.jit(deterministic),
        stochastic=jax.jit(stochastic),
        value=jax.jit(value),
        params=params,
        normalizer=normalizer,
        networks=networks,
        meta=dict(meta or {}),
    )


def traced_action(policy: Policy) -> Callable[[PPOParams, obs_norm.RunningStats, jax.Array], jax.Array]:
    """``act(params, normalizer, obs) -> action``: ``policy``'s deterministic action with its parameters
    as arguments, so that one compiled rollout serves every seed of a run (same network sizes)."""
    networks = policy.networks
    normalized = bool(policy.meta.get("normalize_observations", True))

    def act(params: PPOParams, normalizer: obs_norm.RunningStats, obs: jax.Array) -> jax.Array:
        x = jnp.asarray(obs, jnp.float32)
        x = obs_norm.normalize(normalizer, x) if normalized else x
        mean, _ = networks.policy(params, x)
        return postprocess(mean)

    return act


def select_seed(tree: Any, seed: int) -> Any:
    """Slice learner ``seed`` out of a pytree with a leading seed axis."""
    return jax.tree.map(lambda x: x[seed], tree)


# -------------------------------------------------------------------------------------------- npz I/O


def export_npz(path: str | Path, policy: Policy) -> Path:
    """Write the plain-numpy form of ``policy`` (layout in the module docstring)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays: dict[str, np.ndarray] = {}
    for head, variables in (("policy", policy.params.policy), ("value", policy.params.value)):
        flat = traverse_util.flatten_dict(jax.device_get(variables["params"]), sep="/")
        for name, x in flat.items():
            arrays[f"{head}/{name.removeprefix('mlp/')}"] = np.asarray(x, np.float32)
    normalized = bool(policy.meta.get("normalize_observations", True))
    n = policy.networks.observation_size
    arrays["obs_mean"] = np.asarray(policy.normalizer.mean if normalized else np.zeros(n), np.float32)
    arrays["obs_std"] = np.asarray(policy.normalizer.std if normalized else np.ones(n), np.float32)
    meta = {
        **policy.meta,
        "format": NPZ_FORMAT,
        "observation_size": policy.networks.observation_size,
        "action_size": policy.networks.action_size,
        "hidden_sizes": list(policy.networks.actor.hidden_sizes),
        "normalize_observations": normalized,
        "obs_count": float(policy.normalizer.count) if normalized else 0.0,
    }
    arrays["meta"] = np.asarray(json.dumps(meta))
    atomic.savez(path, **arrays)
    return path


#: ``meta`` keys a policy ``.npz`` must hold (the largest layer width / input size: ``MAX_LAYER_WIDTH``).
NPZ_META_KEYS = ("format", "observation_size", "action_size", "hidden_sizes", "normalize_observations")


def _read_npz_arrays(path: Path) -> dict[str, np.ndarray]:
    """All arrays of a ``.npz`` (never unpickling); UsageError naming the file and what is wrong."""
    name = str(path)
    check_npz_archive(path, f"policy file {name!r}")  # headers only: no Python objects, sizes within memory
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    except Exception as e:  # zipfile, zlib, numpy and OS errors of a damaged archive
        raise UsageError(f"policy file {name!r} is truncated or damaged ({type(e).__name__})") from None
    return arrays


def _npz_meta(name: str, arrays: dict[str, np.ndarray]) -> dict[str, Any]:
    """The ``meta`` JSON of a policy ``.npz``, checked: format/version, sizes, flags."""
    if "meta" not in arrays:
        raise UsageError(f"{name!r} is not a harv_jax policy (no 'meta' entry)")
    try:
        meta = json.loads(str(arrays.pop("meta")))
    except json.JSONDecodeError:
        raise UsageError(f"{name!r}: 'meta' is not valid JSON") from None
    if not isinstance(meta, dict):
        raise UsageError(f"{name!r}: 'meta' must be a JSON object")
    if meta.get("format") != NPZ_FORMAT:
        raise UsageError(f"{name!r} has format {meta.get('format')!r}; this code reads {NPZ_FORMAT}")
    missing = [k for k in NPZ_META_KEYS if k not in meta]
    if missing:
        raise UsageError(f"{name!r}: meta lacks {', '.join(missing)}; needs {', '.join(NPZ_META_KEYS)}")
    sizes = {"observation_size": meta["observation_size"], "action_size": meta["action_size"]}
    hidden = meta["hidden_sizes"]
    if not isinstance(hidden, list) or not hidden:
        raise UsageError(f"{name!r}: hidden_sizes {hidden!r} must be a non-empty list of layer widths")
    sizes.update({f"hidden_sizes[{i}]": h for i, h in enumerate(hidden)})
    for key, v in sizes.items():
        if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= MAX_LAYER_WIDTH:
            raise UsageError(f"{name!r}: {key} {v!r} must be an integer in [1, {MAX_LAYER_WIDTH}]")
    # the measurement path the policy was trained behind: validated here, flown by the registry
    if "measurement_path" in meta:
        path_from_record(meta["measurement_path"], repr(name))
    if not isinstance(meta["normalize_observations"], bool):
        raise UsageError(
            f"{name!r}: normalize_observations {meta['normalize_observations']!r} must be true/false"
        )
    return meta


def _check_array(name: str, key: str, x: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """``x`` if it is a finite float array of ``shape``; else UsageError naming the entry."""
    if x.shape != tuple(shape):
        raise UsageError(f"{name!r}: {key} has shape {x.shape}, expected {tuple(shape)}")
    if not np.issubdtype(x.dtype, np.floating):
        raise UsageError(f"{name!r}: {key} has dtype {x.dtype}, expected floating point")
    if not np.all(np.isfinite(x)):
        raise UsageError(f"{name!r}: {key} holds non-finite values (NaN or inf); the policy is unusable")
    return x


ASSUMED_OBS_COUNT = 1.0e6  # for a file without meta["obs_count"] (written before it was stored)


def _obs_count(name: str, meta: dict[str, Any]) -> float:
    """The normalizer's observation count of a policy file (at least 1); UsageError unless finite, >= 0."""
    count = meta.get("obs_count", ASSUMED_OBS_COUNT)
    if isinstance(count, bool) or not isinstance(count, int | float) or not np.isfinite(count) or count < 0:
        raise UsageError(f"{name!r}: meta obs_count={count!r}; allowed: a finite number >= 0")
    return max(float(count), 1.0)


def _load_npz(path: Path) -> Policy:
    name = str(path)
    arrays = _read_npz_arrays(path)
    meta = _npz_meta(name, arrays)
    networks = make_ppo_networks(meta["observation_size"], meta["action_size"], tuple(meta["hidden_sizes"]))
    template = jax.eval_shape(networks.init, jax.random.key(0))
    heads = {}
    for head, t in (("policy", template.policy), ("value", template.value)):
        flat_t = traverse_util.flatten_dict(t["params"], sep="/")
        flat = {}
        for leaf_name, leaf in flat_t.items():
            key = f"{head}/{leaf_name.removeprefix('mlp/')}"
            if key not in arrays:
                raise UsageError(
                    f"{name!r} lacks the array {key} (shape {leaf.shape}); not a complete policy"
                )
            flat[leaf_name] = jnp.asarray(_check_array(name, key, arrays[key], leaf.shape))
        heads[head] = {"params": traverse_util.unflatten_dict(flat, sep="/")}
    n_obs = meta["observation_size"]
    for key in ("obs_mean", "obs_std"):
        if key not in arrays:
            raise UsageError(f"{name!r} lacks the array {key} (shape ({n_obs},)); not a complete policy")
        _check_array(name, key, arrays[key], (n_obs,))
    if meta["normalize_observations"] and not np.all(arrays["obs_std"] > 0):
        raise UsageError(f"{name!r}: obs_std must be > 0 everywhere")
    params = PPOParams(heads["policy"], heads["value"])
    # (mean, std) weighted by the stored count: a fine-tune (``train --init-policy``) updates the statistics
    # instead of replacing them with its first batch
    count = _obs_count(name, meta)
    std = np.asarray(arrays["obs_std"], np.float64)
    m2 = np.maximum(std**2 - obs_norm.VAR_EPS, 0.0) * count
    normalizer = obs_norm.RunningStats(
        count=jnp.asarray(count, jnp.float32),
        mean=jnp.asarray(arrays["obs_mean"], jnp.float32),
        m2=jnp.asarray(m2, jnp.float32),
    )
    return make_policy(params, normalizer, networks, bool(meta["normalize_observations"]), meta)


def _load_checkpoint(path: Path, seed: int) -> Policy:
    from harv_jax.ppo import checkpoint
    from harv_jax.ppo.config import from_dict

    payload = checkpoint.read(path)
    cfg = from_dict(json.loads(payload["config"]), source=path.name)
    if not 0 <= seed < cfg.num_seeds:
        raise UsageError(f"{path.name}@{seed}: the checkpoint holds seeds 0 to {cfg.num_seeds - 1} only")
    paths = json.loads(payload["paths"])
    meta_sizes = _sizes_from_paths(paths, payload)
    networks = make_ppo_networks(*meta_sizes, cfg.hidden_sizes, cfg.init_log_std)
    template = {
        "params": jax.eval_shape(networks.init, jax.random.key(0)),
        "normalizer": jax.eval_shape(lambda: obs_norm.init_stats(networks.observation_size)),
    }
    leaves_with_path, treedef = jax.tree_util.tree_flatten_with_path(template)
    index = {p: i for i, p in enumerate(paths)}
    out = []
    for kp, leaf in leaves_with_path:
        # template paths "['params'].policy[...]" -> checkpoint paths ".params.policy[...]"
        name = "." + jax.tree_util.keystr(kp)[2:].replace("']", "", 1)
        if name not in index:
            raise UsageError(f"checkpoint {path.name} has no leaf {name}")
        x = np.asarray(payload["leaves"][str(index[name])])[seed]
        if x.shape != leaf.shape:
            raise UsageError(f"checkpoint {path.name}: {name} is {x.shape}, expected {leaf.shape}")
        if not np.all(np.isfinite(x)):
            raise UsageError(
                f"checkpoint {path.name}: {name} of seed {seed} holds NaN or inf; the policy is unusable"
            )
        out.append(jnp.asarray(x))
    tree = jax.tree_util.tree_unflatten(treedef, out)
    meta = {
        "source": str(path),
        "seed": seed,
        "period": payload["period"],
        "normalize_observations": cfg.normalize_observations,
    }
    return make_policy(tree["params"], tree["normalizer"], networks, cfg.normalize_observations, meta)


def _sizes_from_paths(paths: list[str], payload: dict[str, Any]) -> tuple[int, int]:
    obs_i = paths.index(".normalizer.mean")
    log_std_i = paths.index(".params.policy['params']['log_std']")
    obs_size = int(np.asarray(payload["leaves"][str(obs_i)]).shape[-1])
    act_size = int(np.asarray(payload["leaves"][str(log_std_i)]).shape[-1])
    return obs_size, act_size


def load(path: str | Path, seed: int = 0) -> Policy:
    """Load a trained policy from a run folder, a ``.npz`` export or a checkpoint file.

    Args:
        path: ``<run>`` (uses ``<run>/policy/policy.npz``), ``*.npz`` or ``ckpt_*.msgpack``.
        seed: learner index, for checkpoints of multi-seed runs (the ``.npz`` holds one learner).

    Raises:
        UsageError: missing or unreadable file, wrong format or shapes.
    """
    p = Path(path)
    if p.is_dir():
        candidates = [p / "policy" / "policy.npz", p / "policy.npz"]
        found = next((c for c in candidates if c.is_file()), None)
        if found is None:
            raise UsageError(f"no policy.npz in {str(p)!r} (expected {candidates[0]})")
        p = found
    if not p.is_file():
        raise UsageError(f"policy {str(p)!r} does not exist")
    if p.suffix != ".msgpack" and seed != 0:
        raise UsageError(f"policy {str(p)!r}@{seed}: a .npz holds one learner; @SEED is for checkpoints")
    st = p.stat()
    return _load_file(str(p), str(p.resolve()), seed, st.st_mtime_ns, st.st_size)


@functools.lru_cache(maxsize=16)
def _load_file(shown: str, path: str, seed: int, mtime_ns: int, size: int) -> Policy:
    """Read a policy file once per process and file version (a command flying it twice reads it once)."""
    p = Path(shown)
    if p.suffix != ".msgpack":
        return _load_npz(p)
    try:
        return _load_checkpoint(p, seed)
    except UsageError:
        raise
    except (KeyError, IndexError, TypeError, ValueError) as e:
        detail = str(e) if isinstance(e, ValueError) else f"{type(e).__name__}: {e}"
        raise UsageError(f"checkpoint {shown!r} is incomplete ({detail})") from None


def shipped_path(name: str = DEFAULT_SHIPPED) -> Path:
    """Path of a shipped policy (a name of ``harv_jax.policies.SHIPPED``; default ``teacher``)."""
    if name not in SHIPPED:
        raise UsageError(f"shipped policy {name!r} is unknown; allowed: {', '.join(SHIPPED)}")
    from importlib.resources import files

    return Path(str(files("harv_jax.policies") / f"{SHIPPED[name]}.npz"))


def resolve_policy(spec: str | Path | None) -> Policy:
    """Load a policy from a user's path, or ``None``/``"shipped"`` (the default shipped policy,
    ``shipped:robust``), or ``"shipped:<name>"`` (``robust``, ``teacher``, ``fast``, ``recovery``,
    ``paper-full``, ``paper-partial``). A path may end in ``@<seed>`` to pick a learner of a multi-seed
    checkpoint (``ckpt_000010.msgpack@2``)."""
    text = SHIPPED_PREFIX if spec is None else str(spec)
    if text == SHIPPED_PREFIX or text.startswith(SHIPPED_PREFIX + ":"):
        name = text.partition(":")[2] or DEFAULT_SHIPPED
        return load(shipped_path(name))
    path, sep, seed = text.rpartition("@")
    if sep and seed.isascii() and seed.isdigit():
        return load(path, int(seed))
    if sep and Path(path).is_file() and not Path(text).exists():
        raise UsageError(f"policy {text!r}: the learner after '@' must be a whole number >= 0, not {seed!r}")
    return load(text)
