"""A progress reward from a teacher's time to recover: w (T(s) - Gamma T(s')) on every step.

``T`` is a small network (``TimeToGoNet``) fitted to the time a controller (the teacher) still needs to
recover from a state, on the teacher's own flights (``experiments/teacher_recipe/time_to_go_fit.py``). The
env wrapper ``make_progress_env`` adds ``weight_per_s * (T(s_t) - discount * T(s_t+1))`` to the reward of
every step that does not leave the envelope (0 on a terminating step). It is a potential-based term with
potential -weight_per_s T: along any episode its undiscounted sum is weight_per_s (T(s_0) - T(s_N)) whatever
the path between, but each step pays at once for the time to recover it gained or lost, which the policy
gradient's discount (0.99 at 100 Hz: about 1 s) cannot see of a manoeuvre that pays 10-20 s later.

In a preset::

    [env]
    time_to_go = "time_to_go_smc_brake_zoom.npz"   # relative to the preset file's folder
    time_to_go_weight = 100.0      # reward per second of predicted time to recover gained
    time_to_go_discount = 1.0      # Gamma of the term (1: the plain difference)

The file is a plain ``.npz`` (read with ``allow_pickle=False``: loading never executes code) holding the
layers ``w0, b0, w1, b1, ...`` (tanh between them, a linear output) and ``format``/``version`` fields; shapes
and finiteness are validated on load. A run records the file's SHA-256 (``time_to_go_sha256``) when it starts;
``--resume`` refuses the file if it has changed since.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import optax
from flax import struct

from harv_jax.dynamics.state import WIND_INDEX
from harv_jax.env.recovery import Env, with_auto_reset
from harv_jax.errors import UsageError

#: Keys of a run's env settings that add the progress reward (absent: none); a run records the file's SHA-256
#: under ``SHA_KEY`` when it starts, and ``--resume`` refuses a file that has changed since.
FILE_KEY, WEIGHT_KEY, DISCOUNT_KEY = "time_to_go", "time_to_go_weight", "time_to_go_discount"
SHA_KEY = "time_to_go_sha256"
KEYS = (FILE_KEY, WEIGHT_KEY, DISCOUNT_KEY, SHA_KEY)
FORMAT, VERSION = "harv-jax time-to-go", 1
#: The network's inputs, each a function of the wind-axis state (scaled to order one).
FEATURE_NAMES = (
    "(V - 600 ft/s) / 300 ft/s",
    "alpha, rad",
    "beta, rad",
    "p, rad/s",
    "q, rad/s",
    "r, rad/s",
    "sin mu",
    "cos mu",
    "gamma, rad",
    "(h - 20000 ft) / 10000 ft",
)
MAX_WEIGHT_PER_S = 1e4


@struct.dataclass
class TimeToGoNet:
    """Layers [(W [n_in, n_out], b [n_out]), ...] of an MLP: tanh between them, a linear scalar output, s."""

    layers: tuple[tuple[jnp.ndarray, jnp.ndarray], ...]


def features(x_wind: jnp.ndarray) -> jnp.ndarray:
    """The network's inputs [..., 10] (``FEATURE_NAMES``) of wind-axis states [..., 10]."""
    i = WIND_INDEX
    mu = x_wind[..., i["mu"]]
    return jnp.stack(
        [
            (x_wind[..., i["V"]] - 600.0) / 300.0,
            x_wind[..., i["alpha"]],
            x_wind[..., i["beta"]],
            x_wind[..., i["p"]],
            x_wind[..., i["q"]],
            x_wind[..., i["r"]],
            jnp.sin(mu),
            jnp.cos(mu),
            x_wind[..., i["gamma"]],
            (x_wind[..., i["h"]] - 20000.0) / 10000.0,
        ],
        axis=-1,
    )


def _mlp(net: TimeToGoNet, z: jnp.ndarray) -> jnp.ndarray:
    lead = (1,) * (z.ndim - 1)  # the biases broadcast over the leading axes explicitly
    for w, b in net.layers[:-1]:
        z = jnp.tanh(z @ w + b.reshape(lead + b.shape))
    w, b = net.layers[-1]
    return (z @ w + b.reshape(lead + b.shape))[..., 0]


def predict_s(net: TimeToGoNet, x_wind: jnp.ndarray) -> jnp.ndarray:
    """Predicted time to recover [...] (>= 0), s, of wind-axis states [..., 10]."""
    return jnp.maximum(_mlp(net, features(x_wind)), 0.0)


def fit(
    x_wind: np.ndarray,
    time_to_go_s: np.ndarray,
    hidden: tuple[int, ...] = (32, 32),
    steps: int = 6000,
    seed: int = 0,
) -> TimeToGoNet:
    """Least-squares fit of a ``TimeToGoNet`` to states [M, 10] and their times to recover [M], s (Adam,
    minibatches of 4096 drawn with ``seed``)."""
    z = jnp.asarray(features(jnp.asarray(x_wind)), jnp.float32)
    y = jnp.asarray(time_to_go_s, jnp.float32)
    sizes = (z.shape[-1], *hidden, 1)
    key = jax.random.key(seed)
    layers = []
    for n_in, n_out in zip(sizes[:-1], sizes[1:], strict=True):
        key, k = jax.random.split(key)
        layers.append((jax.random.normal(k, (n_in, n_out)) / math.sqrt(n_in), jnp.zeros((n_out,))))
    net = TimeToGoNet(tuple(layers))
    opt = optax.adam(optax.cosine_decay_schedule(3e-3, steps))

    @jax.jit
    def update(net, opt_state, k):
        idx = jax.random.randint(k, (4096,), 0, z.shape[0])
        grad = jax.grad(lambda n: jnp.mean((_mlp(n, z[idx]) - y[idx]) ** 2))(net)
        upd, opt_state = opt.update(grad, opt_state)
        return optax.apply_updates(net, upd), opt_state

    opt_state = opt.init(net)
    for k in jax.random.split(key, steps):
        net, opt_state = update(net, opt_state, k)
    return net


def save(path: Path, net: TimeToGoNet, about: dict[str, Any]) -> None:
    """Write ``net`` as a plain ``.npz`` with ``about`` (JSON) beside its layers."""
    arrays = {}
    for j, (w, b) in enumerate(net.layers):
        arrays[f"w{j}"], arrays[f"b{j}"] = np.asarray(w, np.float32), np.asarray(b, np.float32)
    about_json = json.dumps(about | {"features": list(FEATURE_NAMES)})
    np.savez(path, format=np.str_(FORMAT), version=np.int64(VERSION), about=np.str_(about_json), **arrays)


def load(path: str | Path) -> TimeToGoNet:
    """Read and validate a time-to-go file (``allow_pickle=False``); ValueError naming what is wrong."""
    return load_with_digest(path)[0]


def load_with_digest(path: str | Path) -> tuple[TimeToGoNet, str]:
    """(net, SHA-256 hex digest of the file's bytes): the file is read once, then parsed from memory
    (``allow_pickle=False``) and validated; ValueError naming what is wrong."""
    try:
        raw = Path(path).read_bytes()
        with np.load(io.BytesIO(raw), allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (OSError, ValueError, EOFError) as e:
        raise ValueError(f"time-to-go file {str(path)!r} cannot be read as .npz: {e}") from None
    version = data.get("version")
    versioned = version is not None and version.shape == () and version.dtype.kind in "iu"
    if str(data.get("format", "")) != FORMAT or not versioned or int(version) != VERSION:
        raise ValueError(f"time-to-go file {str(path)!r} is not a {FORMAT!r} file of version {VERSION}")
    layers, n_in = [], len(FEATURE_NAMES)
    for j in range(sum(k.startswith("w") for k in data)):
        w, b = data.get(f"w{j}"), data.get(f"b{j}")
        ok = w is not None and b is not None and w.dtype.kind == b.dtype.kind == "f"
        ok = ok and w.ndim == 2 and w.shape[0] == n_in and b.shape == w.shape[1:]
        if not ok or not (np.all(np.isfinite(w)) and np.all(np.isfinite(b))):
            raise ValueError(
                f"time-to-go file {str(path)!r}: layer {j} is not a finite [{n_in}, n] matrix + [n]"
            )
        layers.append((jnp.asarray(w, jnp.float32), jnp.asarray(b, jnp.float32)))
        n_in = w.shape[1]
    if not layers or n_in != 1:
        raise ValueError(f"time-to-go file {str(path)!r}: the layers must end in one output")
    return TimeToGoNet(tuple(layers)), hashlib.sha256(raw).hexdigest()


def pin_file_digest(env_table: dict[str, Any]) -> dict[str, Any]:
    """``env_table`` with the SHA-256 of its time-to-go file under ``SHA_KEY`` (as it is without a readable
    file, or with a digest already given)."""
    path = env_table.get(FILE_KEY)
    if not isinstance(path, str) or SHA_KEY in env_table:
        return env_table
    try:
        digest = hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError:
        return env_table  # progress_settings names the unreadable file
    return {**env_table, SHA_KEY: digest}


def progress_settings(env_table: dict[str, Any]) -> tuple[TimeToGoNet, float, float] | None:
    """(net, weight_per_s, discount) of a run's env settings, or None without ``time_to_go``; UsageError
    naming a bad value, or a file whose SHA-256 is not the one recorded under ``SHA_KEY``."""
    extra = [k for k in (WEIGHT_KEY, DISCOUNT_KEY, SHA_KEY) if k in env_table and FILE_KEY not in env_table]
    if extra:
        raise UsageError(f"[env] {extra[0]} given without a time-to-go file; set [env] {FILE_KEY} too")
    if FILE_KEY not in env_table:
        return None
    if not isinstance(env_table[FILE_KEY], str):
        raise UsageError(
            f"[env] {FILE_KEY} {env_table[FILE_KEY]!r}; allowed: the path of a time-to-go .npz file"
        )
    weight, discount = env_table.get(WEIGHT_KEY, 100.0), env_table.get(DISCOUNT_KEY, 1.0)
    for name, value, high in ((WEIGHT_KEY, weight, MAX_WEIGHT_PER_S), (DISCOUNT_KEY, discount, 1.0)):
        number = isinstance(value, (int, float)) and not isinstance(value, bool)
        if not number or not 0.0 <= value <= high:
            raise UsageError(f"[env] {name} {value!r}; allowed: a number in [0, {high:g}]")
    try:
        net, digest = load_with_digest(env_table[FILE_KEY])
    except ValueError as e:
        raise UsageError(f"[env] {FILE_KEY}: {e}") from None
    pinned = env_table.get(SHA_KEY)
    if pinned is not None and pinned != digest:
        raise UsageError(
            f"[env] {FILE_KEY}: {str(env_table[FILE_KEY])!r} has SHA-256 {digest}, the run recorded "
            f"{pinned!r}; restore that file or start a new run"
        )
    return net, float(weight), float(discount)


def make_progress_env(env: Env, net: TimeToGoNet, weight_per_s: float, discount: float = 1.0) -> Env:
    """``env`` whose reward gains ``weight_per_s (T(s) - discount T(s'))`` on non-terminating steps;
    ``info["time_to_go_s"]`` is T(s') and ``info["time_to_go_reward"]`` the term paid."""

    def step_no_reset(key: jax.Array, state: Any, action: jnp.ndarray, params: Any):
        obs, new, reward, terminated, truncated, info = env.step_no_reset(key, state, action, params)
        t_next = predict_s(net, new.wind)
        gained = weight_per_s * (predict_s(net, state.wind) - discount * t_next)
        term = jnp.where(terminated | ~jnp.isfinite(gained), 0.0, gained).astype(reward.dtype)
        info["time_to_go_s"], info["time_to_go_reward"] = t_next, term
        return obs, new, reward + term, terminated, truncated, info

    step = with_auto_reset(step_no_reset, env.reset)

    def batch_step(keys: jax.Array, states: Any, actions: jnp.ndarray, params: Any):
        return jax.vmap(step, in_axes=(0, 0, 0, None))(keys, states, actions, params)

    return env._replace(step=step, step_no_reset=step_no_reset, batch_step=batch_step)
