"""Demonstrations for a learned policy: the optimized trajectories in a versioned, pickle-free npz.

Format ``harv_jax.optimal.demos``, version `FORMAT_VERSION` (``numpy.savez_compressed``; every array
is numeric, bool or fixed-width unicode, so ``numpy.load(path, allow_pickle=False)`` reads it). N runs, T
plant steps of ``dt_s`` from engagement:

- ``format`` [] str: ``"harv_jax.optimal.demos"``; ``format_version`` [] int: `FORMAT_VERSION`.
- ``dt_s`` [] float: plant step, s; ``reference_rad`` [3]: target [alpha_d, beta_d, mu_d], rad.
- ``states_wind`` [N, T + 1, 10]: wind states (V ft/s, alpha, beta rad, p, q, r rad/s, mu, gamma, chi rad,
  h ft).
- ``observations`` [N, T, 11]: the policy's observation of each state (``task.spaces.observation``: clipped,
  no noise), as ``control.rl`` builds it in flight.
- ``commands_rad`` [N, T, 3]: deflection commands [de, da, dr], rad (before the actuator model).
- ``actions`` [N, T, 3]: the commands as the policy's normalized actions in [-1, 1] (``command_to_action``).
- ``t_recover_s`` [N]: re-simulated recovery time (standard criterion), s; NaN: not recovered.
- ``recovered`` [N] bool; ``beats_best_controller`` [N] bool: recovers strictly faster than every registry
  controller on that run.

The pair (``observations[:, t]``, ``actions[:, t]``) is what a policy would have had to output at step t
to fly the demonstration. ``harv-jax train --demos FILE`` (``harv_jax.training.demos``) reads this format
with [`load_demos_with_digest`][] and clones the pairs of the recovered runs.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import os
import tempfile
import zipfile
import zlib
from pathlib import Path

import numpy as np

from harv_jax import atomic

#: The format's name and version (a reader refuses any other).
FORMAT_NAME = "harv_jax.optimal.demos"
FORMAT_VERSION = 1
_TRAJ_KEYS = ("states_wind", "observations", "commands_rad", "actions")
_ALL_KEYS = (
    "format",
    "format_version",
    "dt_s",
    "reference_rad",
    *_TRAJ_KEYS,
    "t_recover_s",
    "recovered",
    "beats_best_controller",
)
#: What reading a damaged or foreign file can raise (np.load of a zip, a .npy, a pickle, random bytes).
_READ_ERRORS = (
    OSError,
    ValueError,
    EOFError,
    KeyError,
    AttributeError,
    TypeError,
    zipfile.BadZipFile,
    zlib.error,
)


@dataclasses.dataclass(frozen=True)
class Demos:
    """Validated demonstrations (fields as in the module's table)."""

    dt_s: float
    reference_rad: np.ndarray
    states_wind: np.ndarray
    observations: np.ndarray
    commands_rad: np.ndarray
    actions: np.ndarray
    t_recover_s: np.ndarray
    recovered: np.ndarray
    beats_best_controller: np.ndarray

    @property
    def n_runs(self) -> int:
        """N."""
        return int(self.states_wind.shape[0])


def check_demos_path(path: str | Path) -> Path:
    """ValueError unless ``path`` can be written as a new .npz file (checked before any work is done)."""
    p = Path(path)
    flag = f"--save-demos {str(path)!r}"
    if p.suffix != ".npz":
        raise ValueError(f"{flag} must end in .npz")
    if p.is_dir():
        raise ValueError(f"{flag} is a directory; give a file path ending in .npz")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise ValueError(
            f"{flag}: the folder {str(parent)!r} does not exist; create it or choose another path"
        )
    if p.exists() and not os.access(p, os.W_OK):
        raise ValueError(f"{flag} is not writable; choose a path in a folder you can write to")
    try:  # a real probe: permission bits say nothing for root or on special file systems
        fd, probe = tempfile.mkstemp(dir=parent, suffix=".probe")
        os.close(fd)
        os.unlink(probe)
    except OSError:
        raise ValueError(f"{flag} is not writable; choose a path in a folder you can write to") from None
    return p


def make_demos(
    states_wind: np.ndarray,
    commands_rad: np.ndarray,
    reference_rad: np.ndarray,
    u_min_rad: np.ndarray,
    u_max_rad: np.ndarray,
    t_recover_s: np.ndarray,
    recovered: np.ndarray,
    beats_best_controller: np.ndarray,
    dt_s: float,
) -> Demos:
    """Demos from re-simulated trajectories: the observations and normalized actions are computed here.

    Args:
        states_wind: [N, T + 1, 10]; commands_rad: [N, T, 3]; reference_rad: [3];
        u_min_rad, u_max_rad: [N, 3] or [3] deflection limits; the rest per run [N].
    """
    from harv_jax.task.spaces import command_to_action, observation

    x = np.asarray(states_wind, np.float32)
    ref = np.asarray(reference_rad, np.float32)
    import jax

    obs = np.asarray(jax.vmap(jax.vmap(observation, (0, None)), (0, None))(x[:, :-1], ref), np.float32)
    lo = np.asarray(u_min_rad, np.float32).reshape(-1, 1, 3)
    hi = np.asarray(u_max_rad, np.float32).reshape(-1, 1, 3)
    cmd = np.asarray(commands_rad, np.float32)
    act = np.clip(command_to_action(np.clip(cmd, lo, hi), lo, hi), -1.0, 1.0).astype(np.float32)
    return Demos(
        dt_s=float(dt_s),
        reference_rad=ref,
        states_wind=x,
        observations=obs,
        commands_rad=cmd,
        actions=act,
        t_recover_s=np.asarray(t_recover_s, np.float32),
        recovered=np.asarray(recovered, bool),
        beats_best_controller=np.asarray(beats_best_controller, bool),
    )


def save_demos(path: str | Path, demos: Demos) -> Path:
    """Write ``demos`` (validated first) to ``path`` in the format of the module docstring."""
    _validate({f.name: getattr(demos, f.name) for f in dataclasses.fields(demos)}, str(path))
    arrays = {f.name: np.asarray(getattr(demos, f.name)) for f in dataclasses.fields(demos)}
    with atomic.open_atomic(path, "wb") as f:
        np.savez_compressed(
            f, format=np.array(FORMAT_NAME), format_version=np.array(FORMAT_VERSION, np.int64), **arrays
        )
    return Path(path)


def _validate(d: dict, name: str) -> None:
    """ValueError naming the first problem: shapes, finiteness, action range."""
    x = np.asarray(d["states_wind"])
    if x.ndim != 3 or x.shape[2] != 10 or x.shape[1] < 2:
        raise ValueError(f"demos {name!r}: states_wind has shape {list(x.shape)}, expected [N, T + 1, 10]")
    n, t = x.shape[0], x.shape[1] - 1
    want = {
        "observations": (n, t, 11),
        "commands_rad": (n, t, 3),
        "actions": (n, t, 3),
        "t_recover_s": (n,),
        "recovered": (n,),
        "beats_best_controller": (n,),
        "reference_rad": (3,),
    }
    for k, shape in want.items():
        if tuple(np.shape(d[k])) != shape:
            raise ValueError(f"demos {name!r}: {k} has shape {list(np.shape(d[k]))}, expected {list(shape)}")
    for k in (*_TRAJ_KEYS, "reference_rad"):
        a = np.asarray(d[k])
        if not np.issubdtype(a.dtype, np.floating) or not np.all(np.isfinite(a)):
            raise ValueError(f"demos {name!r}: {k} holds non-finite or non-float values")
    if np.any(np.abs(np.asarray(d["actions"])) > 1.0):
        raise ValueError(f"demos {name!r}: actions lie outside [-1, 1]")
    for k in ("recovered", "beats_best_controller"):
        if np.asarray(d[k]).dtype != bool:
            raise ValueError(f"demos {name!r}: {k} has dtype {np.asarray(d[k]).dtype}, expected bool")
    dt = np.asarray(d["dt_s"])
    if dt.shape != () or not np.issubdtype(dt.dtype, np.number) or not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"demos {name!r}: dt_s {dt!r} must be a positive number")


def load_demos(path: str | Path) -> Demos:
    """Read and validate a demos file (``allow_pickle=False``); ValueError naming what is wrong."""
    return load_demos_with_digest(path)[0]


def load_demos_with_digest(path: str | Path) -> tuple[Demos, str]:
    """(demos, SHA-256 hex digest of the file's bytes): the file is read once, then parsed from memory
    (``allow_pickle=False``: loading never executes code) and validated; ValueError naming what is wrong."""
    name = str(path)
    made_by = "give a file written by harv-jax optimal --save-demos"
    try:
        raw = Path(path).read_bytes()
    except FileNotFoundError:
        raise ValueError(f"demos {name!r} does not exist; {made_by}") from None
    except OSError as e:
        raise ValueError(
            f"demos {name!r} cannot be read ({e.strerror or type(e).__name__}); {made_by}"
        ) from None
    try:
        with np.load(io.BytesIO(raw), allow_pickle=False) as z:
            d = {k: z[k] for k in z.files}
    except _READ_ERRORS as e:
        why = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise ValueError(f"demos {name!r} is not a pickle-free npz file ({why}); {made_by}") from None
    missing = [k for k in _ALL_KEYS if k not in d]
    if missing:
        raise ValueError(f"demos {name!r} lacks {', '.join(missing)}; {made_by}")
    if str(d["format"]) != FORMAT_NAME:
        raise ValueError(f"demos {name!r}: format {str(d['format'])!r}, expected {FORMAT_NAME!r}")
    version = d["format_version"]
    if version.shape != () or not np.issubdtype(version.dtype, np.integer) or int(version) != FORMAT_VERSION:
        raise ValueError(f"demos {name!r}: format_version {version!r}, this reader reads {FORMAT_VERSION}")
    _validate(d, name)
    demos = Demos(
        **{f.name: (float(d[f.name]) if f.name == "dt_s" else d[f.name]) for f in dataclasses.fields(Demos)}
    )
    return demos, hashlib.sha256(raw).hexdigest()
