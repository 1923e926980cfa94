#!/usr/bin/env bash
# The GPU benchmark run: the speed targets' checks on a lent GPU, from the repository root.
#   OUT    results folder (set by the device tool; default /tmp/harv_gpu_out)
#   QUICK  1: each benchmark's --quick form (a dry run on any machine, a few minutes on 2 CPU cores)
# Needs only what the GPU image has (jax, flax, optax, chex, typer, rich, matplotlib); no install. Each step
# has its own time limit, so one slow or hung step leaves the others' JSON. At most 12 minutes (the limits below).
set -uo pipefail
export PYTHONPATH=$PWD PYTHONUNBUFFERED=1
OUT=${OUT:-/tmp/harv_gpu_out}
QUICK=${QUICK:-0}
RES="$OUT/res"
mkdir -p "$RES"
pick() { if [ "$QUICK" = 1 ]; then echo "$1"; else echo "$2"; fi; }  # pick QUICK_VALUE FULL_VALUE

step() {  # step NAME LIMIT_S COMMAND...: run with a time limit, log to $RES/NAME.log, record rc and seconds
  local name=$1 limit=$2
  shift 2
  local t0=$SECONDS
  timeout "$limit" "$@" >"$RES/$name.log" 2>&1
  local rc=$?
  echo "$name rc=$rc ${limit}s-limit took=$((SECONDS - t0))s" | tee -a "$RES/steps.txt"
  tail -n 5 "$RES/$name.log"
}

(nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv || echo "no nvidia-smi") >"$RES/nvidia_smi.txt" 2>&1
python3 -c "import jax; print(jax.__version__, jax.devices())" | tee "$RES/jax.txt"

# the 1000-run Monte Carlo (target: hybrid <= 1 s run time) and the 100 x 100 envelope map, smc and hybrid,
# compile and run separately (each call compiles again: 2 controllers x 3 compiles)
step mc 300 python3 benchmarks/bench_mc.py --controllers smc,hybrid --envelope --repeats 2 $(pick --quick "") \
  --out-dir "$RES"
# PPO training throughput at the paper's network (target: >= 8M env-steps/s at 16,384 envs)
step train 180 python3 benchmarks/bench_train.py --num-envs "$(pick 64 4096,16384)" $(pick --quick "") \
  --out-dir "$RES"
# one closed-loop step: plant, SMC, hybrid variants (absolute times on the GPU)
step step 150 python3 benchmarks/bench_step.py --batch "$(pick 64 16384)" --no-reference \
  $(pick --quick "") --out-dir "$RES"
# dynamics throughput up to 2^20 aircraft
step dynamics 90 python3 benchmarks/bench_dynamics.py --max-batch "$(pick 256 1048576)" $(pick --quick "") \
  --out-dir "$RES"
# harv-jax optimal on 256 Monte Carlo runs (the search's gradients through the closed loop; every compile
# included; the CPU target is 15 minutes on 2 cores). Adds up to 5 minutes to the session.
step optimal 300 python3 benchmarks/bench_optimal.py --runs 256 --seed 2027 $(pick --quick "") --out-dir "$RES"
ls -la "$RES"
