#!/usr/bin/env bash
# The GPU benchmark session (run on the lent H100 from the repository root, OUT set by the device tool).
# Needs only what the GPU image has (jax, flax, optax, chex, typer, rich, matplotlib); no install.
set -uo pipefail
export PYTHONPATH=$PWD PYTHONUNBUFFERED=1
OUT=${OUT:-/tmp/harv_gpu_out}
mkdir -p "$OUT/res"
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv | tee "$OUT/res/nvidia_smi.txt"
python3 -c "import jax; print(jax.__version__, jax.devices())"
python3 benchmarks/bench_dynamics.py --max-batch 1048576 --out-dir "$OUT/res" 2>&1 | tee "$OUT/res/bench_dynamics.log"
python3 benchmarks/bench_env.py --out-dir "$OUT/res" 2>&1 | tee "$OUT/res/bench_env.log"
python3 -m harv_jax.cli mc --controller smc --runs 1000 --chunk 1000 --out "$OUT/res/mc_smc_1000" 2>&1 | tee "$OUT/res/mc.log"
python3 -m harv_jax.cli mc --controller smc --runs 10000 --chunk 10000 --out "$OUT/res/mc_smc_10000" 2>&1 | tee -a "$OUT/res/mc.log"
python3 benchmarks/bench_train.py --out-dir "$OUT/res" 2>&1 | tee "$OUT/res/bench_train.log"
tar czf "$OUT/gpu_bench.tgz" -C "$OUT" res
ls -la "$OUT"
