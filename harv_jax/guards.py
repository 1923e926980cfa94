"""Resource and range guards checked before anything is allocated or compiled.

Each guard raises `UsageError` (a ValueError) with one line naming the value, what
is allowed and why. Memory estimates are deliberately rough upper bounds (bytes per stored float times the
arrays a run keeps), compared with a fraction of the machine's physical memory.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

from harv_jax.errors import UsageError

INT32_MAX = 2**31 - 1
#: Seeds accepted by every command (``jax.random.key`` takes them without overflow on any backend).
SEED_RANGE = (0, INT32_MAX)
#: Fraction of physical memory a single command may plan to use.
MEMORY_FRACTION = 0.5
BYTES_PER_FLOAT = 4
#: Host bytes per simulate step: the float32 rollout (10 states), the float64 table (14 columns) written
#: to CSV and the plotting copies.
SIMULATE_BYTES_PER_STEP = 10 * 4 + 14 * 8 * 3
#: Floats per run and step of one closed-loop chunk kept at full rate (state, surfaces, commands, info).
CLOSED_LOOP_FLOATS_PER_STEP = 48
#: Runs per XLA device in one compiled Monte Carlo / envelope call when ``--chunk`` is not given, on a CPU.
#: Each closed-loop step pays a fixed dispatch cost per compiled operation, whatever the batch, so small
#: chunks run slower: on the 2-core EPYC, 1000 runs x 60 s in chunks of 250 / 500 / 1000 runs (125 / 250 /
#: 500 per device) took 3.6-4.4 / 2.9 / 2.6 s (SMC) and 4.3-5.0 / 3.7 / 3.7-3.8 s (hybrid); 10,000 runs x 5 s
#: were fastest in chunks of 1000-2500 and slower again in chunks of 5000 or more (cache).
AUTO_CHUNK_RUNS_PER_CPU_DEVICE = 512
#: Fraction of physical memory the full-rate data of one automatic chunk may take.
AUTO_CHUNK_MEMORY_FRACTION = 0.125
#: Floats per env and unrolled step of one PPO update (transition, advantages, shuffled minibatch copies).
TRAIN_FLOATS_PER_TRANSITION = 3 * 40
#: Floats per env of the env state (aircraft parameters, tables, actuator and filter state, statistics).
TRAIN_FLOATS_PER_ENV = 4096


def machine_memory_bytes() -> int:
    """Physical memory of this machine, bytes (``os.sysconf``; 8 GiB if the platform does not say)."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return 8 * 2**30


def _gib(n_bytes: float) -> str:
    return f"{n_bytes / 2**30:.3g} GiB"


def check_memory(need_bytes: float, what: str, hint: str) -> None:
    """Raise UsageError if ``need_bytes`` exceeds [`MEMORY_FRACTION`][] of the machine's memory.

    Args:
        need_bytes: estimated bytes the run would hold.
        what: the flags that set the size, as the user typed them (``"--duration 1e+07 s at --dt 0.01 s"``).
        hint: what to change (``"shorten --duration or raise --dt"``).
    """
    budget = MEMORY_FRACTION * machine_memory_bytes()
    if need_bytes > budget:
        raise UsageError(
            f"{what} needs about {_gib(need_bytes)} of memory, more than the {_gib(budget)} allowed "
            f"({MEMORY_FRACTION:.0%} of this machine's {_gib(machine_memory_bytes())}); {hint}"
        )


#: First bytes of a zip archive (a ``.npz``): a local file header, or the end record of an empty archive.
ZIP_MAGIC = (b"PK\x03\x04", b"PK\x05\x06")


def check_npz_archive(path: Path, what: str) -> None:
    """Read only the array headers of the ``.npz`` at ``path``; raise UsageError if the file cannot be read,
    is empty or no zip archive, a member is not a ``.npy`` array, holds Python objects (loading it would need
    pickle), or the arrays declare more bytes than [`check_memory`][] allows. ``what`` names the file in
    the message (``"policy file 'p.npz'"``)."""
    import zipfile

    import numpy as np

    try:
        with path.open("rb") as f:
            head = f.read(4)
    except OSError as e:
        raise UsageError(f"{what} cannot be read ({e.strerror or type(e).__name__})") from None
    if not head:
        raise UsageError(f"{what} is empty (0 bytes); expected a .npz archive")
    if head not in ZIP_MAGIC:
        raise UsageError(f"{what} is not a .npz archive (no zip header)")
    readers = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}
    total = 0
    try:
        with zipfile.ZipFile(path) as z:
            for info in z.infolist():
                with z.open(info) as f:
                    if f.read(6) != np.lib.format.MAGIC_PREFIX:
                        raise UsageError(f"{what}: member {info.filename!r} is not a .npy array")
                    version = tuple(f.read(2))
                    if version not in readers:
                        raise UsageError(f"{what}: {info.filename} has .npy format {version}; not supported")
                    shape, _, dtype = readers[version](f)
                if dtype.hasobject:
                    raise UsageError(
                        f"{what} holds Python objects ({info.filename}), which are never loaded; expected "
                        "plain numeric arrays"
                    )
                total += math.prod(shape) * dtype.itemsize
    except UsageError:
        raise
    except Exception as e:  # zipfile, zlib, numpy header and OS errors of a damaged archive
        raise UsageError(f"{what} is truncated or damaged ({type(e).__name__})") from None
    check_memory(total, f"{what} ({total:,} bytes of arrays)", "check the file")


def check_seed(seed: int, flag: str = "--seed") -> int:
    """Return ``seed`` if it is an integer in [`SEED_RANGE`][], else raise UsageError."""
    lo, hi = SEED_RANGE
    if isinstance(seed, bool) or not isinstance(seed, int) or not lo <= seed <= hi:
        raise UsageError(f"{flag} {seed!r} is outside the allowed seeds [{lo}, {hi}]")
    return seed


def check_steps(n_steps: int, what: str, hint: str) -> None:
    """Raise UsageError if a step count does not fit the int32 counters of the compiled loops."""
    if n_steps > INT32_MAX:
        raise UsageError(f"{what} is {n_steps:,} steps, more than the {INT32_MAX:,} allowed; {hint}")


def check_simulate(duration_s: float, dt_s: float) -> None:
    """Guard ``harv-jax simulate``: step count and host memory of the trajectory (rollout, CSV table)."""
    what = f"--duration {duration_s:g} s at --dt {dt_s:g} s"
    steps = duration_s / dt_s
    if not steps < INT32_MAX:  # also inf and nan, which round() cannot take
        raise UsageError(
            f"{what} is more than the {INT32_MAX:,} steps allowed; shorten --duration or raise --dt"
        )
    n_steps = round(steps)
    check_steps(n_steps, what, "shorten --duration or raise --dt")
    check_memory(
        n_steps * SIMULATE_BYTES_PER_STEP, f"{what} ({n_steps:,} steps)", "shorten --duration or raise --dt"
    )


def closed_loop_chunk_bytes(runs: int, n_steps: int) -> int:
    """Rough bytes of the full-rate data of ``runs`` closed-loop runs of ``n_steps`` steps in one call."""
    return runs * n_steps * CLOSED_LOOP_FLOATS_PER_STEP * BYTES_PER_FLOAT


def auto_chunk(runs: int, n_steps: int, n_devices: int = 1, runs_per_device: int | None = None) -> int:
    """Runs per compiled call when none is given.

    ``runs_per_device`` runs per device (``None``: all runs, as on a GPU), at most
    [`AUTO_CHUNK_MEMORY_FRACTION`][] of the machine's memory at full rate, a multiple of ``n_devices``
    (at least ``n_devices``, the runs are sharded over them), and within the int32 step counters.
    """
    if runs < 1 or n_steps < 1 or n_devices < 1:
        raise ValueError(f"runs={runs}, n_steps={n_steps}, n_devices={n_devices}: each must be >= 1")
    memory_share = int(AUTO_CHUNK_MEMORY_FRACTION * machine_memory_bytes())
    by_memory = memory_share // closed_loop_chunk_bytes(1, n_steps)
    by_device = runs if runs_per_device is None else runs_per_device * n_devices
    chunk = max(1, min(runs, by_memory, by_device, INT32_MAX // n_steps))
    if n_devices > 1:
        chunk = max(n_devices, chunk - chunk % n_devices)
    return chunk


def check_closed_loop_batch(
    runs: int,
    n_steps: int,
    record_every: int,
    chunk: int | None,
    n_controllers: int,
    runs_flag: str = "--runs",
) -> None:
    """Guard a Monte Carlo / envelope: full-rate data of one chunk plus every run's decimated history.

    Args:
        runs: runs per controller.
        n_steps: plant steps per run.
        record_every: decimation of the kept alpha/beta/mu history (``n_steps``: one sample per run).
        chunk: runs per compiled call (``None``: [`auto_chunk`][], which stays within its memory share).
        n_controllers: controllers flown (their histories are all kept).
        runs_flag: the flag that set ``runs`` (``--runs``, ``--n``).
    """
    if chunk is None:  # the largest automatic chunk (one device): it is sized to fit memory
        chunk = auto_chunk(runs, n_steps)
    chunk = min(chunk, runs)
    check_steps(chunk * n_steps, f"--chunk {chunk} x {n_steps:,} steps per run", "lower --chunk")
    chunk_bytes = closed_loop_chunk_bytes(chunk, n_steps)
    history_bytes = n_controllers * runs * (n_steps // max(record_every, 1) + 1) * 3 * BYTES_PER_FLOAT
    check_memory(
        chunk_bytes + history_bytes,
        f"{runs_flag} {runs:,} x {n_steps:,} steps x {n_controllers} controller(s) (--chunk {chunk})",
        "lower the runs, --duration or --chunk",
    )


#: Widest hidden layer and most hidden layers of a policy or value network.
MAX_LAYER_WIDTH = 65_536
MAX_HIDDEN_LAYERS = 64
#: Copies of every network weight a training run holds: parameters, gradients, Adam's two moments.
TRAIN_COPIES_PER_WEIGHT = 4


def check_network(hidden_sizes: tuple[int, ...], num_seeds: int) -> None:
    """Guard the hidden layers of ``num_seeds`` actor-critic pairs: depth, width, and the memory of their
    hidden weights in training ([`TRAIN_COPIES_PER_WEIGHT`][] copies; input and output layers are small)."""
    if len(hidden_sizes) > MAX_HIDDEN_LAYERS:
        raise UsageError(
            f"hidden_sizes has {len(hidden_sizes)} layers; at most {MAX_HIDDEN_LAYERS} are allowed"
        )
    for i, h in enumerate(hidden_sizes):
        if h > MAX_LAYER_WIDTH:
            raise UsageError(f"hidden_sizes[{i}] = {h} is wider than the {MAX_LAYER_WIDTH:,} allowed")
    weights = sum(a * b for a, b in zip(hidden_sizes, hidden_sizes[1:], strict=False)) + sum(hidden_sizes)
    need = 2 * num_seeds * weights * TRAIN_COPIES_PER_WEIGHT * BYTES_PER_FLOAT
    check_memory(
        need,
        f"hidden_sizes {list(hidden_sizes)} x --seeds {num_seeds}",
        "use narrower hidden layers or fewer --seeds",
    )


def check_train(total_steps: int, num_envs: int, unroll: int, num_seeds: int, gradient_steps: int) -> None:
    """Guard ``harv-jax train``: int32 sizes of the compiled update and the memory of one update.

    Args:
        total_steps: env steps per seed (``--steps``).
        num_envs: parallel envs per seed (``--num-envs``).
        unroll: rollout length per update.
        num_seeds: learners trained together (``--seeds``).
        gradient_steps: optimizer steps of the whole run (updates x epochs x minibatches), counted in int32
            by the optimizer's schedule.
    """
    if gradient_steps > INT32_MAX:
        raise UsageError(
            f"--steps {total_steps:,} needs {gradient_steps:,} optimizer steps, more than the {INT32_MAX:,} "
            "the optimizer counts; lower --steps or raise --num-envs / --unroll"
        )
    transitions = num_seeds * num_envs * unroll
    if transitions > INT32_MAX:
        raise UsageError(
            f"--num-envs {num_envs:,} x --unroll {unroll} x --seeds {num_seeds} = {transitions:,} "
            f"transitions per update, more than the {INT32_MAX:,} an array may index; lower --num-envs, "
            "--unroll or --seeds"
        )
    need = (
        num_seeds * num_envs * (unroll * TRAIN_FLOATS_PER_TRANSITION + TRAIN_FLOATS_PER_ENV) * BYTES_PER_FLOAT
    )
    check_memory(
        need,
        f"--num-envs {num_envs:,} x --unroll {unroll} x --seeds {num_seeds}",
        "lower --num-envs or --seeds",
    )
