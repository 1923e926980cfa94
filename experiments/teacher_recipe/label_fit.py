"""How well can the teacher's labels be fitted from the observations? A diagnostic of the cloning error.

A run's env (its stored settings, the teacher riding along) is flown by one of the run's policies (its
Gaussian mean) from ``--envs`` resets of draw seed ``--draw-seed`` for ``--steps`` steps; an episode's samples
end at its termination. On those states it reports, per channel (the env's action order), the squared error
between the policy's action and the teacher's label, the share of labels at a bound (|a| > 0.99) and of label
switches (a label moving by > 0.5 in one step), and the error of a fresh network of the policy's width fitted
offline to the same (observation, label) pairs (Adam, ``--fit-steps`` steps of 4096 samples, on the first 80%
of the envs; scored on both parts). With ``--finetune-out`` the policy's own actor is fitted the same way (its
observation statistics kept) and written as a policy file: one round of DAgger with the whole round's data
aggregated, which ``harv-jax mc`` can fly. ``--rounds N`` makes it N rounds: each refitted policy flies
``--envs`` fresh resets (draw seed ``--draw-seed`` + round), its flights join the earlier ones, and the actor
is fitted again to all of them (Ross et al. 2011). ``--channel-weights`` weighs the channels in the refit's
loss; ``--rate-weight R`` adds R times the squared error of the action's change from one step to the next
against the label's change (consecutive alive steps of the same flight), so the refit copies how the
teacher's command moves as well as where it is. ``--speed-weight V_REF`` weighs each sample of the refit by
1 + (V / V_REF)^2 (V its observed airspeed, ft/s), since a deflection error costs a moment that grows with the
dynamic pressure; the JSON then also gives each flying policy's error by airspeed band.

    python experiments/teacher_recipe/label_fit.py runs/tuning_v48_teacher_zoom_wide_dagger_seed7 --seed 0 \\
        --envs 2048 --steps 1000 --finetune-out runs/v48_seed0_refit.npz --out label_fit.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np
import optax

from harv_jax import policy as policy_io
from harv_jax.ppo import normalize as obs_norm
from harv_jax.ppo.checkpoint import stored_configs
from harv_jax.training.environment import make_harv_env


def load_run(run: Path, seed: int, nominal: bool) -> tuple[Any, Any, Any, list]:
    """The run's training env (its stored settings), its params, policy ``seed`` and its hidden widths."""
    cfg, env_table = stored_configs(run)
    if nominal:
        env_table = {**env_table, "domain_randomization": False}
    env, params = make_harv_env(env_table)
    pol = policy_io.load(run / "policy" / f"policy_seed{seed}.npz")
    return env, params, pol, list(cfg.hidden_sizes)


def fly(env, params, pol, envs: int, steps: int, draw_seed: int) -> dict:
    """Observations, policy actions, teacher labels and the alive mask [envs, steps, ...] of ``pol`` (its
    Gaussian mean) flying ``env`` from ``envs`` resets of ``draw_seed``."""
    keys = jax.random.split(jax.random.key(draw_seed), envs)

    def one(key):
        obs, state = env.reset(key, params)

        def body(carry, k):
            obs, state, alive = carry
            a = pol.deterministic(obs)
            obs2, state2, _, term, trunc, info = env.step_no_reset(k, state, a, params)
            out = (obs, a, info["teacher_action"], alive)
            alive2 = alive & ~term & ~trunc
            return (obs2, state2, alive2), out

        _, out = jax.lax.scan(body, (obs, state, jnp.bool_(True)), jax.random.split(key, steps))
        return out

    obs, act, lab, alive = jax.jit(jax.vmap(one))(keys)
    return {
        "obs": np.asarray(obs),
        "act": np.asarray(act),
        "lab": np.asarray(lab),
        "alive": np.asarray(alive),
    }


class MLP(nn.Module):
    hidden: tuple[int, ...]
    out: int

    @nn.compact
    def __call__(self, x):
        for h in self.hidden:
            x = nn.tanh(nn.Dense(h)(x))
        return nn.Dense(self.out)(x)


def own_errors(d: dict) -> np.ndarray:
    """[alive samples, channels] squared error of the flying policy's action against the teacher's label."""
    m = d["alive"]
    return (d["act"][m] - d["lab"][m]) ** 2


def alive_pairs(alive: np.ndarray) -> np.ndarray:
    """[envs, steps - 1] mask of the steps t whose step t + 1 is alive too (alive [envs, steps])."""
    return alive[:, 1:] & alive[:, :-1]


def n_train_envs(d: dict) -> int:
    """How many of the flights (the first 80% of the envs) are the fit's train part."""
    return int(0.8 * d["alive"].shape[0])


def own_rates(d: dict) -> dict[str, list[float]]:
    """Per channel, over the steps where both ends are alive: the mean |change per step| of the flying
    policy's action and of the teacher's label, and the mean squared difference of the two changes."""
    m = alive_pairs(d["alive"])
    da, dl = np.diff(d["act"], axis=1)[m], np.diff(d["lab"], axis=1)[m]
    return {
        "policy_abs_rate": np.abs(da).mean(0).tolist(),
        "label_abs_rate": np.abs(dl).mean(0).tolist(),
        "rate_sq_error": ((da - dl) ** 2).mean(0).tolist(),
    }


AIRSPEED_BANDS_FPS = (0.0, 400.0, 600.0, 1000.0, float("inf"))


def errors_by_airspeed(d: dict, err: np.ndarray) -> dict[str, list[float]]:
    """Per observed-airspeed band (``AIRSPEED_BANDS_FPS``): the mean over the band's alive samples of ``err``
    (:func:`own_errors` of ``d``), per channel (empty band: NaN)."""
    v = d["obs"][d["alive"]][:, 0]
    out = {}
    for lo, hi in zip(AIRSPEED_BANDS_FPS[:-1], AIRSPEED_BANDS_FPS[1:], strict=True):
        s = (v >= lo) & (v < hi)
        out[f"{lo:.0f}-{hi:.0f}"] = err[s].mean(0).tolist() if s.any() else [float("nan")] * err.shape[1]
    return out


def split(d: dict, key: str) -> tuple[np.ndarray, np.ndarray]:
    """The alive samples of ``d[key]``: (the first 80% of the envs, the rest), each [samples, ...]."""
    n_train = n_train_envs(d)
    part = lambda s: d[key][s].reshape(-1, d[key].shape[-1])[d["alive"][s].reshape(-1)]  # noqa: E731
    return part(slice(0, n_train)), part(slice(n_train, None))


def pooled(rounds: list[dict], key: str) -> tuple[np.ndarray, np.ndarray]:
    """The train parts of every round's ``key`` stacked (the aggregate); the held-out part of the last."""
    parts = [split(d, key) for d in rounds]
    return np.concatenate([tr for tr, _ in parts]), parts[-1][1]


def pooled_pairs(rounds: list[dict]) -> tuple[np.ndarray, np.ndarray]:
    """Consecutive alive steps of every round's train part: observations [pairs, 2, obs] and labels
    [pairs, 2, channels] (step t, step t + 1)."""
    xs, ys = [], []
    for d in rounds:
        n_train = n_train_envs(d)
        m = alive_pairs(d["alive"][:n_train])
        for key, out in (("obs", xs), ("lab", ys)):
            v = d[key][:n_train]
            out.append(np.stack([v[:, :-1][m], v[:, 1:][m]], axis=1))
    return np.concatenate(xs), np.concatenate(ys)


def fit(
    apply_fn,
    params,
    x_tr,
    y_tr,
    steps: int,
    lr: float,
    key: jax.Array,
    weights=None,
    rate=None,
    speed_ref=None,
):
    """Adam (cosine decay from ``lr``), ``steps`` minibatches of 4096: mean over samples of
    sum_channels w_c (clip(apply_fn(params, x), -1, 1) - y)^2 (``weights`` w [3]; None: every w_c = 1),
    each sample times 1 + (V / ``speed_ref``)^2 where ``speed_ref`` (ft/s) is given (V: the raw
    observation's airspeed, x[:, 0]).
    ``rate`` (R, x pairs [P, 2, obs], y pairs [P, 2, channels]) adds R times the mean over 4096 pairs of
    sum_channels w_c (change of the clipped output from step t to t + 1 - the label's change)^2."""
    x_tr, y_tr = jnp.asarray(x_tr), jnp.asarray(y_tr)
    opt = optax.adam(optax.cosine_decay_schedule(lr, steps))
    st = opt.init(params)
    w = None if weights is None else jnp.asarray(weights, y_tr.dtype)

    def loss(p, x, y):
        sq = (jnp.clip(apply_fn(p, x), -1, 1) - y) ** 2
        if speed_ref is not None:
            sq = sq * (1.0 + (x[:, :1] / speed_ref) ** 2)
        return jnp.mean(jnp.sum(sq if w is None else sq * w, -1))

    def rate_loss(p, xp, yp):
        a = jnp.clip(apply_fn(p, xp.reshape(-1, xp.shape[-1])), -1, 1).reshape(yp.shape)
        sq = ((a[:, 1] - a[:, 0]) - (yp[:, 1] - yp[:, 0])) ** 2
        return jnp.mean(jnp.sum(sq if w is None else sq * w, -1))

    if rate is None:
        objective = loss
    else:
        r_w, xp_tr, yp_tr = rate[0], jnp.asarray(rate[1]), jnp.asarray(rate[2])

        def objective(p, x, y, k):
            j = jax.random.randint(jax.random.fold_in(k, 1), (4096,), 0, xp_tr.shape[0])
            return loss(p, x, y) + r_w * rate_loss(p, xp_tr[j], yp_tr[j])

    @jax.jit
    def update(p, st, k):
        i = jax.random.randint(k, (4096,), 0, x_tr.shape[0])
        extra = () if rate is None else (k,)
        u, st = opt.update(jax.grad(objective)(p, x_tr[i], y_tr[i], *extra), st)
        return optax.apply_updates(p, u), st

    for k in jax.random.split(key, steps):
        params, st = update(params, st, k)
    return params


def channel_errors(apply_fn, params, x_tr, y_tr, x_te, y_te) -> dict[str, list[float]]:
    """Per-channel mean squared error of clip(apply_fn(params, x), -1, 1) on both parts."""
    err = lambda x, y: np.mean((np.clip(np.asarray(apply_fn(params, x)), -1, 1) - y) ** 2, 0).tolist()  # noqa: E731
    return {"train": err(x_tr, y_tr), "test": err(x_te, y_te)}


def offline_fit(d: dict, hidden, steps: int, seed: int = 0) -> dict[str, list[float]]:
    """A fresh MLP fitted to the labels on the first 80% of the envs; per-channel squared errors of both."""
    (x_tr, x_te), (y_tr, y_te) = split(d, "obs"), split(d, "lab")
    mu, sd = x_tr.mean(0), x_tr.std(0) + 1e-6
    x_tr, x_te = (x_tr - mu) / sd, (x_te - mu) / sd
    net = MLP(tuple(hidden), y_tr.shape[-1])
    p = fit(
        net.apply, net.init(jax.random.key(seed), x_tr[:1]), x_tr, y_tr, steps, 1e-3, jax.random.key(seed + 1)
    )
    return channel_errors(net.apply, p, x_tr, y_tr, x_te, y_te)


def finetune(
    pol,
    rounds: list[dict],
    steps: int,
    lr: float,
    seed: int = 0,
    weights=None,
    rate_weight=None,
    speed_ref=None,
):
    """The policy's own actor fitted further to the labels of every round's train part (channel weights
    ``weights``, the label-change term of weight ``rate_weight`` and the airspeed weight of ``speed_ref``,
    see :func:`fit`), as a Policy;
    per-channel errors on that aggregate and on the last round's held-out flights."""
    (x_tr, x_te), (y_tr, y_te) = pooled(rounds, "obs"), pooled(rounds, "lab")

    def mean_of(pp, x):
        return pol.networks.policy(pol.params._replace(policy=pp), obs_norm.normalize(pol.normalizer, x))[0]

    rate = None if rate_weight is None else (rate_weight, *pooled_pairs(rounds))
    pp = fit(
        mean_of, pol.params.policy, x_tr, y_tr, steps, lr, jax.random.key(seed + 2), weights, rate, speed_ref
    )
    new = policy_io.make_policy(pol.params._replace(policy=pp), pol.normalizer, pol.networks, meta=pol.meta)
    return new, channel_errors(mean_of, pp, x_tr, y_tr, x_te, y_te)


def dagger(env, params, pol, first: dict, args) -> tuple[Any, list[dict]]:
    """``args.rounds`` rounds of DAgger with the data aggregated (Ross et al. 2011): fit the actor to every
    round's labels so far, fly the fitted policy from fresh resets (draw seed ``args.draw_seed`` + round),
    add its flights; per round the flying policy's error on its own flights and the fit's errors."""
    rounds, log = [first], []
    for r in range(args.rounds):
        pol, fit_err = finetune(
            pol,
            rounds,
            args.fit_steps,
            args.finetune_lr,
            r,
            args.weights,
            args.rate_weight,
            args.speed_weight,
        )
        entry = {"round": r, "samples": int(sum(d["alive"].sum() for d in rounds)), "fit": fit_err}
        if r + 1 < args.rounds:
            rounds.append(fly(env, params, pol, args.envs, args.steps, args.draw_seed + r + 1))
            err = own_errors(rounds[-1])
            entry["next_policy_sq_error_on_own_flights"] = err.mean(0).tolist()
            if args.rate_weight is not None:
                entry["next_policy_rates_on_own_flights"] = own_rates(rounds[-1])
            if args.speed_weight is not None:
                entry["next_policy_sq_error_by_airspeed"] = errors_by_airspeed(rounds[-1], err)
        log.append(entry)
    return pol, log


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", type=Path)
    ap.add_argument("--seed", type=int, default=0, help="which of the run's policies flies")
    ap.add_argument("--envs", type=int, default=256)
    ap.add_argument("--steps", type=int, default=2000, help="env steps per env (20 s)")
    ap.add_argument("--draw-seed", type=int, default=77, help="reset draws (no evaluation uses 77)")
    ap.add_argument("--fit-steps", type=int, default=20000)
    ap.add_argument("--nominal", action="store_true", help="fly the nominal aircraft (no randomization)")
    ap.add_argument(
        "--finetune-out", type=Path, help="also fit the policy's own actor offline; write it here"
    )
    ap.add_argument("--finetune-lr", type=float, default=3e-4)
    ap.add_argument("--rounds", type=int, default=1, help="DAgger rounds of the refit (data aggregated)")
    ap.add_argument("--skip-fresh", action="store_true", help="no fresh-network fit (only --finetune-out)")
    ap.add_argument(
        "--channel-weights", help="W0,W1,W2: the action channels' weights in the refit's loss (default 1,1,1)"
    )
    ap.add_argument(
        "--rate-weight",
        type=float,
        help="R: add R x the squared error of the action's change per step against the label's to the refit",
    )
    ap.add_argument(
        "--speed-weight",
        type=float,
        metavar="V_REF",
        help="weigh each sample of the refit by 1 + (V / V_REF)^2 (V its observed airspeed, ft/s)",
    )
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args()
    if a.speed_weight is not None and not (np.isfinite(a.speed_weight) and a.speed_weight > 0):
        ap.error(f"--speed-weight {a.speed_weight}: allowed: a finite airspeed > 0 (ft/s)")
    if a.rate_weight is not None and not (np.isfinite(a.rate_weight) and a.rate_weight >= 0):
        ap.error(f"--rate-weight {a.rate_weight}: allowed: a finite number >= 0")
    if a.rounds < 1:
        ap.error(f"--rounds {a.rounds}: must be >= 1")
    a.weights = None
    if a.channel_weights is not None:
        try:
            a.weights = [float(w) for w in a.channel_weights.split(",")]
        except ValueError:
            a.weights = []
        if len(a.weights) != 3 or not all(np.isfinite(w) and w > 0 for w in a.weights):
            ap.error(f"--channel-weights {a.channel_weights!r}: allowed: three positive numbers, e.g. 4,1,1")
    env, params, pol, hidden = load_run(a.run, a.seed, a.nominal)
    d = fly(env, params, pol, a.envs, a.steps, a.draw_seed)
    m = d["alive"]
    lab = d["lab"][m]
    switch = np.abs(np.diff(d["lab"], axis=1)) > 0.5
    switch = np.concatenate([np.zeros_like(switch[:, :1]), switch], axis=1)[m]
    err = own_errors(d)
    res = {
        "run": str(a.run),
        "policy_seed": a.seed,
        "envs": a.envs,
        "steps": a.steps,
        "draw_seed": a.draw_seed,
        "nominal_aircraft": a.nominal,
        "samples": int(m.sum()),
        "policy_sq_error_per_channel": err.mean(0).tolist(),
        "label_at_bound_share_per_channel": (np.abs(lab) > 0.99).mean(0).tolist(),
        "label_switch_share_per_channel": switch.mean(0).tolist(),
        "policy_sq_error_share_on_switch_steps": (
            (err * switch).sum(0) / np.maximum(err.sum(0), 1e-12)
        ).tolist(),
        "offline_fit_hidden": hidden,
        "offline_fit_steps": a.fit_steps,
    }
    if not a.skip_fresh:
        res["offline_fit_sq_error_per_channel"] = offline_fit(d, hidden, a.fit_steps)
    if a.finetune_out is not None:
        new, log = dagger(env, params, pol, d, a)
        policy_io.export_npz(a.finetune_out, new)
        res["finetune_out"] = str(a.finetune_out)
        res["finetune_lr"] = a.finetune_lr
        if a.weights is not None:
            res["finetune_channel_weights"] = a.weights
        if a.rate_weight is not None:
            res["finetune_rate_weight"] = a.rate_weight
            res["policy_rates_on_own_flights"] = own_rates(d)
        if a.speed_weight is not None:
            res["finetune_speed_weight_ref_fps"] = a.speed_weight
            res["policy_sq_error_by_airspeed"] = errors_by_airspeed(d, err)
        res["finetune_sq_error_per_channel"] = log[-1]["fit"]
        if a.rounds > 1:
            res["dagger_rounds"] = log
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(res, indent=1))
    print(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
