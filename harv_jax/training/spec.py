"""One training run, specified: the [`TrainSpec`][] parsed once from a preset and the command line.

Everything below ``harv-jax train`` reads the spec (the env, the trainer and its loss terms, the evaluation
hook, the outputs); its cross-field rules are checked here, once, when it is made:

- behaviour cloning (``bc_coef`` or ``bc_coef_end`` > 0) needs a teacher or demonstrations, and
  demonstrations are cloned only with it;
- a teacher cannot be combined with a controller in the loop;
- a privileged critic needs a measurement path;
- ``--target-recovery`` is in (0, 1].

The spec is written into the run folder (``config.json``: preset, PPO config, env settings with the wrapper
keys, initial policy, target, demonstrations) and read back by ``--resume`` (from ``config.json`` or a
checkpoint), so a resumed run is the same run.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from harv_jax.control.registry import controller_names, parse_measurement_path, uses_option
from harv_jax.env.env_settings import EnvSettings
from harv_jax.errors import UsageError
from harv_jax.ppo import config as ppo_config
from harv_jax.ppo.config import PPOConfig
from harv_jax.task.measurement_path import MeasurementPath
from harv_jax.training.in_loop import LOOP_KEY, parse_loop
from harv_jax.training.measured_env import CRITIC_KEY, CRITICS, MEASUREMENT_PATH_KEY
from harv_jax.training.teacher import TEACHER_KEY

WRAPPER_KEYS = (LOOP_KEY, TEACHER_KEY, MEASUREMENT_PATH_KEY, CRITIC_KEY)


def check_measurement_path(text: Any, loop: str) -> None:
    """``[env] measurement_path``: ``none``, ``lpHZ``, ``obsHZ`` or ``esoHZ``; not with a controller in the
    loop."""
    if not isinstance(text, str):
        raise UsageError(f"[env] measurement_path {text!r}: allowed: none, lpHZ, obsHZ or esoHZ (e.g. lp2)")
    if parse_measurement_path(text, "[env] measurement_path") is not None and loop != "none":
        raise UsageError(
            f"[env] measurement_path {text!r} cannot be combined with --in-loop; drop one of them"
        )


def check_critic(critic: Any, measurement_path: Any) -> None:
    """``[env] critic``: ``actor`` or ``privileged``; the privileged critic needs a measurement path (what
    the critic sees beyond the policy is the state before the sensors and the path)."""
    if critic not in CRITICS:
        raise UsageError(f"[env] critic {critic!r}; allowed: {', '.join(CRITICS)}")
    if critic == "privileged" and measurement_path == "none":
        raise UsageError(
            '[env] critic "privileged" sees the true state behind a measurement path, and this run has '
            'none; set [env] measurement_path (e.g. "lp2") or critic = "actor"'
        )


def check_wrappers(loop: str, teacher: Any) -> None:
    """The rules of the wrapper keys: a teacher is a model-based registry controller and excludes a
    controller in the loop."""
    if teacher is not None:
        teachers = [n for n in controller_names() if not uses_option([n], "policy")]  # model-based
        if not isinstance(teacher, str) or teacher not in teachers:
            raise UsageError(
                f"[env] teacher {teacher!r} is not a controller that can teach; allowed: "
                f"{', '.join(teachers)}"
            )
        if loop != "none":
            raise UsageError(f"[env] teacher {teacher!r} cannot be combined with --in-loop; drop one of them")


def check_env_table(env_table: Any) -> EnvSettings:
    """The env settings of a preset or record, with its wrapper keys, validated (not the rules that involve
    the PPO settings, which the command line may still change); UsageError naming the first bad value."""
    if not isinstance(env_table, dict):
        raise UsageError(f"[env] must be a table of settings, got {env_table!r}")
    env = EnvSettings.from_table({k: v for k, v in env_table.items() if k not in WRAPPER_KEYS})
    check_wrappers(parse_loop(env_table.get(LOOP_KEY, "none")), env_table.get(TEACHER_KEY))
    check_measurement_path(
        env_table.get(MEASUREMENT_PATH_KEY, "none"), parse_loop(env_table.get(LOOP_KEY, "none"))
    )
    check_critic(env_table.get(CRITIC_KEY, "actor"), env_table.get(MEASUREMENT_PATH_KEY, "none"))
    return env


@dataclass(frozen=True)
class TrainSpec:
    """A training run's whole specification (frozen, validated when made).

    Attributes:
        preset: the preset it was made from (a shipped name or a ``.toml`` path).
        ppo: the PPO configuration (``[ppo]`` plus command-line overrides).
        env: the env settings (``[env]`` fields, ``[reward]``, ``[randomization]``, ``[spin]``, ``[eval]``).
        loop: ``none`` or ``hybrid:<schedule>``: a controller in the env step (``--in-loop``).
        teacher: a model-based registry controller that labels every state (``[env] teacher``), or None.
        init_policy: the policy every seed starts from (``--init-policy``), or None.
        target_recovery: stop once every seed recovers this fraction of the ``[eval]`` batch, or None.
        demos_sha256: the SHA-256 the demonstrations file must have (a resumed run's), or None.
        measurement_path: ``none`` or the path the policy observes through (``[env] measurement_path``:
            ``lpHZ``, ``obsHZ``, ``esoHZ``; ``harv_jax.training.measured_env``).
        critic: what the critic observes, ``actor`` (the policy's observation) or ``privileged`` (the true
            state; ``[env] critic``, with a measurement path).
    """

    preset: str
    ppo: PPOConfig
    env: EnvSettings
    loop: str = "none"
    teacher: str | None = None
    init_policy: str | None = None
    target_recovery: float | None = None
    demos_sha256: str | None = None
    measurement_path: str = "none"
    critic: str = "actor"

    def __post_init__(self) -> None:
        check_wrappers(self.loop, self.teacher)
        check_measurement_path(self.measurement_path, self.loop)
        check_critic(self.critic, self.measurement_path)
        cfg = self.ppo
        if (cfg.bc_coef > 0 or cfg.bc_coef_end > 0) and self.teacher is None and cfg.demos is None:
            raise UsageError(
                f"bc_coef {cfg.bc_coef:g} / bc_coef_end {cfg.bc_coef_end:g} clone a teacher, and this run "
                'has none; set [env] teacher = "smc-brake" (or another model-based controller), give '
                "demonstrations (--demos FILE) or set both to 0"
            )
        if cfg.demos is not None and not (cfg.bc_coef > 0 or cfg.bc_coef_end > 0):
            raise UsageError(
                f"--demos {cfg.demos!r} are cloned with weight bc_coef; set bc_coef > 0 or bc_coef_end > 0"
            )
        t = self.target_recovery
        if t is not None and not (math.isfinite(t) and 0 < t <= 1):
            raise UsageError(f"--target-recovery {t} must be in (0, 1]")

    @property
    def behaviour_cloning(self) -> bool:
        """Whether the run clones a teacher or demonstrations."""
        return self.ppo.bc_coef > 0 or self.ppo.bc_coef_end > 0

    def replace(self, **changes: Any) -> TrainSpec:
        """A copy with fields changed, checked again."""
        return dataclasses.replace(self, **changes)

    @classmethod
    def from_settings(
        cls,
        preset: str,
        ppo: PPOConfig,
        env_table: dict[str, Any],
        init_policy: str | None = None,
        target_recovery: float | None = None,
        demos_sha256: str | None = None,
    ) -> TrainSpec:
        """The spec of a PPO config and an env settings dict that may hold the wrapper keys (``loop``,
        ``teacher``), as a preset's ``[env]`` table or a run's record does."""
        if not isinstance(env_table, dict):
            raise UsageError(f"[env] must be a table of settings, got {env_table!r}")
        env = EnvSettings.from_table({k: v for k, v in env_table.items() if k not in WRAPPER_KEYS})
        if init_policy is not None and not isinstance(init_policy, str):
            raise UsageError(f"init_policy {init_policy!r} must be a policy spec (a string)")
        return cls(
            preset=preset,
            ppo=ppo,
            env=env,
            loop=parse_loop(env_table.get(LOOP_KEY, "none")),
            teacher=env_table.get(TEACHER_KEY),
            init_policy=init_policy,
            target_recovery=target_recovery,
            demos_sha256=demos_sha256,
            measurement_path=env_table.get(MEASUREMENT_PATH_KEY, "none"),
            critic=env_table.get(CRITIC_KEY, "actor"),
        )

    def env_settings(self) -> dict[str, Any]:
        """The env settings as a run records them (``config.json`` ``env``, checkpoints' ``env_config``):
        the env's settings with the wrapper keys that are set."""
        out = self.env.table()
        if self.loop != "none":
            out[LOOP_KEY] = self.loop
        if self.teacher is not None:
            out[TEACHER_KEY] = self.teacher
        if self.measurement_path != "none":
            out[MEASUREMENT_PATH_KEY] = self.measurement_path
        if self.critic != "actor":
            out[CRITIC_KEY] = self.critic
        return out

    @property
    def path(self) -> MeasurementPath | None:
        """The measurement path the policy observes through, or None."""
        return parse_measurement_path(self.measurement_path, "[env] measurement_path")

    def record(self, demos: dict[str, Any] | None = None) -> dict[str, Any]:
        """``config.json``'s content: preset, PPO config, env settings, initial policy, target and the
        demonstrations' record (``demos``: path, SHA-256, runs)."""
        out: dict[str, Any] = {
            "preset": self.preset,
            "ppo": ppo_config.to_dict(self.ppo),
            "env": self.env_settings(),
        }
        if self.init_policy is not None:
            out["init_policy"] = self.init_policy
        if demos is not None:
            out["demos"] = demos
        if self.target_recovery is not None:
            out["target_recovery"] = self.target_recovery
        return out

    @classmethod
    def from_record(cls, record: dict[str, Any], source: str) -> TrainSpec:
        """The spec of a run's ``config.json`` content; UsageError naming ``source`` for a bad one."""
        if not isinstance(record, dict):
            raise UsageError(f"{source}: not a run record")
        cfg = ppo_config.from_dict(record["ppo"], source=source)
        demos = record.get("demos")
        sha = demos.get("sha256") if isinstance(demos, dict) else None
        target = record.get("target_recovery")
        try:
            return cls.from_settings(
                str(record.get("preset", "?")),
                cfg,
                record.get("env", {}),
                record.get("init_policy"),
                float(target) if isinstance(target, int | float) and not isinstance(target, bool) else None,
                sha if isinstance(sha, str) else None,
            )
        except UsageError as e:
            raise UsageError(f"{source}: {e}") from None
