"""Every seed of a training run on the conditions a user judges a policy by: ``harv-jax evaluate``.

A *cell* is one controller on one condition: the per-run recovered flags, recovery times, control total
variation and chatter of a Monte Carlo (or of the 30 s spin). The conditions (`CONDITIONS`) draw their
runs from one Monte Carlo seed (common random numbers: every controller of a condition flies the same
runs):

- ``clean``: nominal aircraft, no disturbance (``harv-jax mc``);
- ``randomized``: the randomized aircraft (``--randomize``);
- ``disturbed``: ``--disturbances default`` (noise, delay, model error, lag, moderate turbulence; the
  criterion in turbulence);
- ``noise3``: sensor noise at 3x the env's maximum alone; ``model2``: model error at 2x the ranges alone;
- ``spin``: the 30 s developed spin of the nominal aircraft (``harv-jax compare``'s), one run.

Each seed's policy flies RL-only (``rl``) and in the default hybrid (``hybrid``, schedule
``control.registry.DEFAULT_ZETA``), behind the measurement path it carries (as ``--controller rl`` flies
it); the reference controllers fly once per condition: the SMC (behind its 2 Hz low-pass ``smc+lp2`` in the
noisy conditions: in turbulence the 0.1 Hz observer lags the air-relative angles, ``experiments/turbulence``)
and ``smc-brake-zoom``. A policy's rollout is
compiled once per condition and controller kind with the policy's parameters as arguments, so the seeds
share it. Cells are written as they finish (``cells/<condition>/<controller>.npz``, atomically) and a
re-run with the same settings reuses them (``--resume``).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax import atomic
from harv_jax.aircraft.params import AircraftParams
from harv_jax.control.hybrid.settings import DEFAULT_ZETA
from harv_jax.control.registry import build_controller, policy_controller, policy_path
from harv_jax.evaluation.closed_loop import closed_loop, score
from harv_jax.evaluation.montecarlo.disturbances import DisturbanceSpec, parse_disturbances
from harv_jax.evaluation.montecarlo.inputs import MCInputs, sample_mc_inputs
from harv_jax.evaluation.montecarlo.rollout import run_mc, shard_runs
from harv_jax.guards import AUTO_CHUNK_RUNS_PER_CPU_DEVICE, auto_chunk
from harv_jax.policy import Policy, traced_action
from harv_jax.task.measurement_path import MeasurementPath
from harv_jax.task.spec import ALPHA_TARGET_RAD, DT_S, H0_FT
from harv_jax.task.spin_bank import nominal_spin

#: The policy's controller kinds.
POLICY_CONTROLLERS = ("rl", "hybrid")
#: The model-based controller every condition also flies (the project's best).
BRAKE_ZOOM = "smc-brake-zoom"


@dataclass(frozen=True)
class Condition:
    """One evaluation condition.

    Attributes:
        name: its name (``--conditions``).
        disturbances: the Monte Carlo's disturbances (None: the spin).
        reference: the reference controller the ratios are taken against.
        text: what it is.
    """

    name: str
    disturbances: DisturbanceSpec | None
    reference: str
    text: str

    @property
    def baselines(self) -> tuple[str, ...]:
        """The model-based controllers flown once on this condition."""
        return tuple(dict.fromkeys((self.reference, BRAKE_ZOOM)))


#: The conditions, in report order.
CONDITIONS: dict[str, Condition] = {
    c.name: c
    for c in (
        Condition("clean", parse_disturbances("none"), "smc", "nominal aircraft, no disturbance"),
        Condition(
            "randomized",
            parse_disturbances("none", randomize=True),
            "smc",
            "randomized aircraft (--randomize)",
        ),
        Condition(
            "disturbed",
            parse_disturbances("default"),
            "smc+lp2",
            "--disturbances default: noise, delay, model error, lag, moderate turbulence",
        ),
        Condition("noise3", parse_disturbances("noise", {"noise": 3.0}), "smc+lp2", "sensor noise x3 alone"),
        Condition("model2", parse_disturbances("model", {"model": 2.0}), "smc", "model error x2 alone"),
        Condition("spin", None, "smc", "the 30 s developed spin of the nominal aircraft, one run"),
    )
}


@dataclass(frozen=True)
class EvalSettings:
    """What an evaluation flies (its record decides whether stored cells can be reused).

    Attributes:
        runs: Monte Carlo runs per condition.
        mc_seed: the Monte Carlo's seed.
        duration_s: run length, s.
        conditions: the conditions' names, in order.
        alpha_d_rad: target angle of attack, rad.
        zeta: the hybrid's schedule.
    """

    runs: int
    mc_seed: int
    duration_s: float
    conditions: tuple[str, ...]
    alpha_d_rad: float = ALPHA_TARGET_RAD
    zeta: str = DEFAULT_ZETA

    def record(self) -> dict[str, Any]:
        """The settings as JSON."""
        return {
            "runs": self.runs,
            "mc_seed": self.mc_seed,
            "duration_s": self.duration_s,
            "conditions": list(self.conditions),
            "alpha_d_rad": self.alpha_d_rad,
            "zeta": self.zeta,
        }


def file_sha256(path: Path) -> str:
    """SHA-256 of a file's bytes."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def condition_inputs(cond: Condition, settings: EvalSettings, nominal: AircraftParams) -> MCInputs:
    """The Monte Carlo runs of a condition (every condition from the same seed)."""
    return sample_mc_inputs(
        jax.random.key(settings.mc_seed), settings.runs, nominal, h0_ft=H0_FT, disturbances=cond.disturbances
    )


def _policy_controller(
    kind: str, act: Callable, params: Any, normalizer: Any, zeta: str, path: MeasurementPath | None
):
    """The policy as ``kind`` (rl, hybrid), behind the measurement path it was trained behind (if any), as
    ``control.registry`` builds it."""
    return policy_controller(kind, lambda obs: act(params, normalizer, obs), zeta, path)


def _cell(recovered: Any, t_recover_s: Any, tv: Any, chatter: Any) -> dict[str, np.ndarray]:
    rec = np.asarray(recovered, bool).reshape(-1)
    t = np.asarray(t_recover_s, np.float64).reshape(-1)
    return {
        "recovered": rec,
        "t_recover_s": np.where(rec, t, np.nan),
        "tv_rad": np.asarray(tv, np.float64).reshape(rec.size, -1).sum(-1),
        "chatter_rad2": np.asarray(chatter, np.float64).reshape(rec.size, -1).sum(-1),
    }


def _from_metrics(m: Any) -> dict[str, np.ndarray]:
    return _cell(m.recovered, m.t_recover_s, m.control_tv_rad, m.chatter_index_rad2)


class Evaluator:
    """Flies the cells of one evaluation; compiled rollouts are kept per (condition, controller kind).

    Args:
        settings: what to fly.
        policies: the seeds' policies (same networks).
        nominal: the nominal aircraft.
    """

    def __init__(self, settings: EvalSettings, policies: list[Policy], nominal: AircraftParams) -> None:
        self.settings = settings
        self.policies = policies
        self.nominal = nominal
        self.n_steps = int(round(settings.duration_s / DT_S))
        self.reference = jnp.asarray([settings.alpha_d_rad, 0.0, 0.0], jnp.float32)
        self._compiled: dict[tuple[str, str], Any] = {}
        self._inputs: dict[str, Any] = {}
        self._act = traced_action(policies[0])
        paths = {json.dumps(p.meta.get("measurement_path"), sort_keys=True) for p in policies}
        if len(paths) > 1:
            raise ValueError("the seeds' policies carry different measurement paths; one run has one")
        self.path = policy_path(policies[0])

    def inputs(self, cond: Condition) -> Any:
        """The condition's runs (cached)."""
        if cond.name not in self._inputs:
            if cond.disturbances is None:
                self._inputs[cond.name] = nominal_spin(self.nominal)
            else:
                self._inputs[cond.name] = condition_inputs(cond, self.settings, self.nominal)
        return self._inputs[cond.name]

    def baseline(self, cond: Condition, name: str) -> dict[str, np.ndarray]:
        """A model-based controller on a condition."""
        controller = build_controller(name)
        if cond.disturbances is None:
            return self._spin(controller)
        out, _ = run_mc(controller, self.inputs(cond), self.reference, self.n_steps)
        return _from_metrics(out.metrics)

    def _spin(self, controller: Any) -> dict[str, np.ndarray]:
        x0, d0 = self.inputs(CONDITIONS["spin"])
        res = closed_loop(
            controller, self.nominal, x0, self.reference, jax.random.key(0), self.n_steps, DT_S, d0
        )
        m, _ = score(res, self.reference, self.nominal, DT_S)
        return _from_metrics(m)

    def policy_cell(self, cond: Condition, kind: str, seed: int) -> dict[str, np.ndarray]:
        """Seed ``seed``'s policy as ``kind`` (rl, hybrid) on a condition."""
        pol = self.policies[seed]
        fn = self._policy_fn(cond, kind)
        m = fn(pol.params, pol.normalizer)
        return _from_metrics(jax.device_get(m))

    def _policy_fn(self, cond: Condition, kind: str) -> Callable[[Any, Any], Any]:
        key = (cond.name, kind)
        if key in self._compiled:
            return self._compiled[key]
        act, zeta, n_steps, ref, dt = self._act, self.settings.zeta, self.n_steps, self.reference, DT_S
        path = self.path
        if cond.disturbances is None:
            x0, d0 = self.inputs(cond)
            nominal = self.nominal

            @jax.jit
            def spin(params, normalizer):
                c = _policy_controller(kind, act, params, normalizer, zeta, path)
                res = closed_loop(c, nominal, x0, ref, jax.random.key(0), n_steps, dt, d0)
                return score(res, ref, nominal, dt)[0]

            self._compiled[key] = spin
            return spin
        inputs = self.inputs(cond)
        n = int(inputs.x0_wind.shape[0])
        n_dev = jax.local_device_count()
        per_device = AUTO_CHUNK_RUNS_PER_CPU_DEVICE if jax.default_backend() == "cpu" else None
        chunk = max(1, min(auto_chunk(n, n_steps, n_dev, per_device), n))
        if n_dev > 1:
            chunk = max(n_dev, chunk - chunk % n_dev)
        n_chunks = -(-n // chunk)
        pad = n_chunks * chunk - n
        padded = jax.tree.map(lambda a: jnp.concatenate([a, jnp.repeat(a[:1], pad, 0)]) if pad else a, inputs)

        def one_run(c, run):
            res = closed_loop(
                c, run.params, run.x0_wind, ref, run.keys, n_steps, dt,
                disturbance=run.disturbance, disturbance_key=run.disturbance_keys,
                max_delay_steps=run.max_delay_steps, model_params=run.model_params,
            )  # fmt: skip
            tparams = None if run.disturbance is None else run.disturbance.turbulence
            return score(res, ref, run.params, dt, turbulence=tparams)[0]

        @jax.jit
        def chunk_fn(params, normalizer, runs):
            c = _policy_controller(kind, act, params, normalizer, zeta, path)
            return jax.vmap(lambda run: one_run(c, run))(runs)

        def fly(params, normalizer):
            outs = []
            for i in range(n_chunks):
                part = shard_runs(jax.tree.map(lambda a, i=i: a[i * chunk : (i + 1) * chunk], padded), n_dev)
                outs.append(jax.device_get(chunk_fn(params, normalizer, part)))
            return jax.tree.map(lambda *xs: np.concatenate(xs)[:n], *outs)

        self._compiled[key] = fly
        return fly


# ----------------------------------------------------------------------------------------------- cells


def cell_path(out: Path, condition: str, controller: str) -> Path:
    """Where a cell is stored (``controller``: a baseline's name or ``rl_seed<i>``/``hybrid_seed<i>``)."""
    return out / "cells" / condition / f"{controller.replace('+', '_')}.npz"


def write_cell(path: Path, cell: dict[str, np.ndarray], stamp: dict[str, Any]) -> None:
    """Store a cell with the stamp of what produced it (settings and policy digest)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic.savez(path, stamp=np.frombuffer(json.dumps(stamp, sort_keys=True).encode(), np.uint8), **cell)


def read_cell(path: Path, stamp: dict[str, Any], runs: int) -> dict[str, np.ndarray] | None:
    """A stored cell if it exists, was produced with ``stamp`` and holds ``runs`` finite-shaped runs; None
    otherwise (it is then flown again). Reads plain arrays only (no pickle)."""
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as z:
            if bytes(z["stamp"]).decode() != json.dumps(stamp, sort_keys=True):
                return None
            cell = {k: np.asarray(z[k]) for k in ("recovered", "t_recover_s", "tv_rad", "chatter_rad2")}
    except (OSError, ValueError, KeyError):
        return None
    if any(v.shape != (runs,) for v in cell.values()) or cell["recovered"].dtype != bool:
        return None
    return cell
