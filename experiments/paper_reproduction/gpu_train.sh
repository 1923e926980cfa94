#!/usr/bin/env bash
# Train the paper's presets on the lent H100 (3 seeds each, vmapped in one graph); OUT set by the device tool.
set -uo pipefail
export PYTHONPATH=$PWD PYTHONUNBUFFERED=1
OUT=${OUT:-/tmp/harv_gpu_train}
mkdir -p "$OUT"
for preset in paper-partial paper-full; do
  /usr/bin/time -v python3 -m harv_jax.cli train --preset "$preset" --seeds 3 --seed 0 --out "$OUT/$preset" \
    > "$OUT/$preset.log" 2>&1
  tail -n 25 "$OUT/$preset.log"
done
# results come back as files of at most 16 MiB: runs without checkpoints, and the last checkpoints apart
# (train_last_ckpts.tgz: training state, not committed; a run that needs resuming is re-run)
tar czf "$OUT/train_runs.tgz" -C "$OUT" --exclude='ckpt_*' paper-partial paper-full paper-partial.log paper-full.log
last_ckpts=$(cd "$OUT" && for d in paper-partial paper-full; do ls "$d"/checkpoints/ckpt_*.msgpack | tail -n 1; done)
tar czf "$OUT/train_last_ckpts.tgz" -C "$OUT" $last_ckpts
rm -rf "$OUT/paper-partial" "$OUT/paper-full"
ls -la "$OUT"
