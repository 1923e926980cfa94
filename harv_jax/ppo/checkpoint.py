"""Atomic training checkpoints: msgpack (flax.serialization) + fsync + atomic rename. Never pickle.

A checkpoint is one file ``checkpoints/ckpt_<period>.msgpack`` holding every leaf of the
[`TrainingState`][harv_jax.ppo.train_state.TrainingState] (params, optimizer state, normaliser, env state,
PRNG keys as raw key data, counters) with its tree path, shape and dtype; the PPO config; the env config; the
period index and the metrics history. It is written to a temporary file in the same folder, flushed, fsynced
and renamed over the final name, so a SIGKILL leaves either the previous checkpoint or the new one, never a
torn file. The newest ``KEEP`` checkpoints are kept. Each file carries a SHA-256 of its header and leaves,
so a file torn or damaged afterwards (a full disk, a copy cut short, bit rot) is recognised:
[`latest_intact`][] skips it and falls back to the newest intact one, and [`set_aside`][] renames it
``*.corrupt`` so that it is neither loaded nor counted by the pruning. Loading checks the format name and
version, the checksum (files written before it existed have none), the config, and every leaf's path, shape
and dtype against the state the current code would build; any mismatch is a one-line UsageError.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from pathlib import Path
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from flax import serialization

from harv_jax import manifest
from harv_jax.errors import UsageError
from harv_jax.ppo import config as ppo_config
from harv_jax.ppo.config import PPOConfig

FORMAT = "harv_jax.ppo.checkpoint"
VERSION = 1
KEEP = 2
_NAME = re.compile(r"^ckpt_(\d{6,})\.msgpack$")
_TMP = re.compile(r"^\.tmp-(\d+)-ckpt_\d{6,}\.msgpack$")
#: Header fields covered by the checksum, in order (then every leaf's dtype, shape and bytes).
_DIGEST_FIELDS = (
    "format",
    "version",
    "period",
    "env_steps",
    "config",
    "env_config",
    "history",
    "paths",
    "key_leaves",
)


class Restored(NamedTuple):
    """A loaded checkpoint: state (host numpy / key arrays), periods done, history, configs, the file used
    and the newer files skipped as damaged ((path, reason) pairs, newest first)."""

    state: Any
    period: int
    history: list[dict[str, Any]]
    config: dict[str, Any]
    env_config: dict[str, Any]
    path: Path | None = None
    skipped: tuple[tuple[Path, str], ...] = ()


class Choice(NamedTuple):
    """The checkpoint [`latest_intact`][] picked: its path and payload, and the newer files it skipped."""

    path: Path
    payload: dict[str, Any]
    skipped: tuple[tuple[Path, str], ...]


def _is_key(x: Any) -> bool:
    return jnp.issubdtype(getattr(x, "dtype", np.float32), jax.dtypes.prng_key)


def _flatten(tree: Any) -> tuple[list[str], list[Any], Any]:
    leaves_with_path, treedef = jax.tree_util.tree_flatten_with_path(tree)
    paths = [jax.tree_util.keystr(p) for p, _ in leaves_with_path]
    return paths, [x for _, x in leaves_with_path], treedef


def _history_to_json(history: list[dict[str, Any]]) -> str:
    def conv(v: Any) -> Any:
        a = np.asarray(v)
        return a.tolist() if a.ndim else a.item()

    return json.dumps([{k: conv(v) for k, v in row.items()} for row in history], allow_nan=True)


def _history_from_json(text: str) -> list[dict[str, Any]]:
    rows = json.loads(text)
    return [
        {k: (np.asarray(v, np.float32) if isinstance(v, list) else v) for k, v in row.items()} for row in rows
    ]


def _to_host(x: Any) -> Any:
    """A leaf as a value every process can fetch: arrays sharded over several processes (the env axis in a
    multi-process run) are all-gathered first (``multihost_utils.process_allgather``, a collective)."""
    if isinstance(x, jax.Array) and not x.is_fully_addressable:
        from jax.experimental import multihost_utils

        return multihost_utils.process_allgather(x, tiled=True)
    return x


def _digest(payload: dict[str, Any]) -> str:
    """SHA-256 (hex) of the header fields and of every leaf's dtype, shape and bytes."""
    h = hashlib.sha256()
    for k in _DIGEST_FIELDS:
        h.update(f"{k}={payload[k]!r};".encode())
    leaves = payload["leaves"]
    for i in range(len(leaves)):
        x = np.ascontiguousarray(leaves[str(i)])
        h.update(f"{i}:{x.dtype.str}:{x.shape};".encode())
        h.update(x.tobytes())
    return h.hexdigest()


def checkpoint_paths(ckpt_dir: str | Path) -> list[Path]:
    """Complete checkpoint files in ``ckpt_dir``, oldest first (temporary files are ignored)."""
    d = Path(ckpt_dir)
    if not d.is_dir():
        return []
    found = [(int(m.group(1)), p) for p in d.iterdir() if (m := _NAME.match(p.name))]
    return [p for _, p in sorted(found)]


def save(
    ckpt_dir: str | Path,
    state: Any,
    cfg: PPOConfig,
    period: int,
    history: list[dict[str, Any]],
    env_config: dict[str, Any],
) -> Path:
    """Write ``ckpt_<period>.msgpack`` atomically and prune old checkpoints; returns its path.

    In a multi-process run every process must call this (the env-sharded leaves are all-gathered); only
    process 0 writes, so ``ckpt_dir`` must be on a filesystem that all processes see when they resume.
    """
    d = Path(ckpt_dir)
    paths, orig, _ = _flatten(state)
    leaves = jax.device_get([_to_host(jax.random.key_data(x) if _is_key(x) else x) for x in orig])
    final = d / f"ckpt_{period:06d}.msgpack"
    if jax.process_index() != 0:  # multi-process: every process gathers (a collective), process 0 writes
        return final
    d.mkdir(parents=True, exist_ok=True)
    payload = {
        "format": FORMAT,
        "version": VERSION,
        "period": int(period),
        "env_steps": int(period * ppo_config.steps_per_period(cfg)),
        "config": json.dumps(ppo_config.to_dict(cfg)),
        "env_config": json.dumps(env_config),
        "history": _history_to_json(history),
        "paths": json.dumps(paths),
        "key_leaves": json.dumps([i for i, x in enumerate(orig) if _is_key(x)]),
        "leaves": {str(i): np.asarray(x) for i, x in enumerate(leaves)},
    }
    payload["sha256"] = _digest(payload)
    data = serialization.msgpack_serialize(payload)
    tmp = d / f".tmp-{os.getpid()}-{final.name}"
    with open(tmp, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, final)
    manifest.record(final)
    dir_fd = os.open(d, os.O_RDONLY)
    try:
        os.fsync(dir_fd)
    finally:
        os.close(dir_fd)
    for old in checkpoint_paths(d)[:-KEEP]:
        old.unlink(missing_ok=True)
    return final


def read(path: str | Path) -> dict[str, Any]:
    """Read and check the header of one checkpoint file; returns the raw payload (leaves as numpy)."""
    p = Path(path)
    if not p.is_file():
        raise UsageError(f"checkpoint {str(p)!r} does not exist")
    try:
        data = p.read_bytes()
    except OSError as e:
        raise UsageError(f"checkpoint {str(p)!r} cannot be read ({e.strerror or type(e).__name__})") from None
    try:
        payload = serialization.msgpack_restore(data)
    except Exception as e:  # msgpack raises several types on corrupt input
        raise UsageError(
            f"checkpoint {str(p)!r} is unreadable (truncated or damaged: {type(e).__name__})"
        ) from None
    if not isinstance(payload, dict) or payload.get("format") != FORMAT:
        raise UsageError(f"{str(p)!r} is not a harv_jax PPO checkpoint")
    if payload.get("version") != VERSION:
        raise UsageError(
            f"checkpoint {str(p)!r} has version {payload.get('version')}; this code reads {VERSION}"
        )
    if "sha256" in payload:  # files written before the checksum existed have none
        try:
            ok = _digest(payload) == payload["sha256"]
        except (KeyError, TypeError, ValueError):
            ok = False
        if not ok:
            raise UsageError(f"checkpoint {str(p)!r} is corrupt (its checksum does not match its content)")
    return payload


def latest_intact(ckpt_dir: str | Path) -> Choice | None:
    """The newest checkpoint in ``ckpt_dir`` that reads and verifies, with the newer ones skipped and why.

    Returns None if the folder holds no checkpoint file at all.

    Raises:
        UsageError: there are checkpoint files but none of them is intact.
    """
    files = checkpoint_paths(ckpt_dir)
    skipped: list[tuple[Path, str]] = []
    for path in reversed(files):
        try:
            return Choice(path, read(path), tuple(skipped))
        except UsageError as e:
            skipped.append((path, str(e)))
    if files:
        raise UsageError(
            f"none of the {len(files)} checkpoint(s) in {str(ckpt_dir)!r} is intact "
            f"(newest: {skipped[0][1]}); start the run again with --force"
        )
    return None


def set_aside(path: str | Path) -> Path:
    """Rename a damaged checkpoint to ``<name>.corrupt`` (kept for inspection, no longer loaded or pruned)."""
    p = Path(path)
    target = p.with_name(p.name + ".corrupt")
    os.replace(p, target)
    return target


def remove_stale_tmp(ckpt_dir: str | Path) -> list[Path]:
    """Delete temporary files that a killed [`save`][] of another process left in ``ckpt_dir``."""
    d = Path(ckpt_dir)
    if not d.is_dir():
        return []
    stale = [p for p in d.iterdir() if (m := _TMP.match(p.name)) and int(m.group(1)) != os.getpid()]
    for p in stale:
        p.unlink(missing_ok=True)
    return stale


def unflatten_into(payload: dict[str, Any], template: Any, source: str = "checkpoint") -> Any:
    """Rebuild a pytree shaped like ``template`` (arrays or ShapeDtypeStructs) from a payload's leaves.

    Raises:
        UsageError: a leaf path, shape or dtype differs from the template.
    """
    t_paths, t_leaves, treedef = _flatten(template)
    paths = json.loads(payload["paths"])
    if paths != t_paths:
        missing = sorted(set(t_paths) - set(paths))[:1] or sorted(set(paths) - set(t_paths))[:1]
        raise UsageError(f"{source} does not match this model/env (tree differs at {missing or 'order'})")
    out = []
    for i, (path, t) in enumerate(zip(t_paths, t_leaves, strict=True)):
        x = np.asarray(payload["leaves"][str(i)])
        if _is_key(t):
            want = jax.eval_shape(jax.random.key_data, t)
            if x.shape != want.shape or x.dtype != want.dtype:
                raise UsageError(f"{source}: key {path} has shape {x.shape}, expected {want.shape}")
            out.append(jax.random.wrap_key_data(jnp.asarray(x)))
            continue
        if x.shape != tuple(t.shape) or x.dtype != np.dtype(t.dtype):
            raise UsageError(
                f"{source}: {path} is {x.dtype}{list(x.shape)}, expected {np.dtype(t.dtype)}{list(t.shape)}"
            )
        out.append(x)
    return jax.tree_util.tree_unflatten(treedef, out)


def restore_latest(ckpt_dir: str | Path, template: Any, cfg: PPOConfig) -> Restored:
    """Load the newest checkpoint in ``ckpt_dir`` into the structure of ``template``.

    Args:
        ckpt_dir: the run's ``checkpoints/`` folder.
        template: the state the current code builds (e.g. ``jax.eval_shape`` of ``Trainer.init``).
        cfg: the config the run continues with; it must equal the stored one.

    Damaged newer files are skipped (see [`latest_intact`][]; ``Restored.skipped`` lists them); they are
    not renamed here ([`set_aside`][] does that).

    Raises:
        UsageError: no checkpoint, none intact, wrong version, different config, or mismatched leaves.
    """
    choice = latest_intact(ckpt_dir)
    if choice is None:
        raise UsageError(f"no checkpoint found in {str(ckpt_dir)!r}")
    payload = choice.payload
    stored = json.loads(payload["config"])
    # settings added after a checkpoint was written are absent there; their defaults keep the old behaviour
    stored = {**ppo_config.to_dict(ppo_config.PPOConfig()), **stored}
    current = ppo_config.to_dict(cfg)
    diff = sorted(k for k in set(stored) | set(current) if stored.get(k) != current.get(k))
    if diff:
        k = diff[0]
        raise UsageError(
            f"checkpoint config differs from this run's: {k}={stored.get(k)!r} vs {current.get(k)!r}"
        )
    state = unflatten_into(payload, template, source=f"checkpoint {choice.path.name}")
    return Restored(
        state=state,
        period=int(payload["period"]),
        history=_history_from_json(payload["history"]),
        config=stored,
        env_config=json.loads(payload["env_config"]),
        path=choice.path,
        skipped=choice.skipped,
    )


def stored_configs(run_dir: str | Path) -> tuple[PPOConfig, dict[str, Any]]:
    """(PPO config, env config) of the newest intact checkpoint under ``run_dir/checkpoints``."""
    choice = latest_intact(Path(run_dir) / "checkpoints")
    if choice is None:
        raise UsageError(f"no checkpoint found in {str(Path(run_dir) / 'checkpoints')!r}")
    payload = choice.payload
    return ppo_config.from_dict(json.loads(payload["config"]), source=choice.path.name), json.loads(
        payload["env_config"]
    )
