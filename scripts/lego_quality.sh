#!/usr/bin/env bash
# Train S-AssetField and the TensoRF-VM baseline on the real lego scene for 10 minutes,
# evaluate, continue the same runs to 30 minutes, evaluate again.
#
#   scripts/lego_quality.sh [TEST_EVERY]
#
# TEST_EVERY: evaluate every n-th of the 200 test views (default 1 = all of them).
# Budgets use `--clock cpu` (fair on a busy machine). Output under runs/lego/; finished
# steps are skipped, so the script can be stopped and started again.
set -euo pipefail
cd "$(dirname "$0")/.."
EVERY=${1:-1}
DATA=${DATA:-../shared/data/nerf_synthetic_lego_400}
BIN=${BIN:-target/release/assetfield}
[ -x "$BIN" ] || cargo build --release --locked
OUT=runs/lego
mkdir -p "$OUT/logs"
# both 10-minute runs first, then both continued to 30 minutes
for minutes in 10 30; do
  for model in s vm; do
    field="$OUT/lego_$model.safetensors"
    eval_dir="$OUT/eval_${model}_$minutes"
    [ -f "$eval_dir/metrics.json" ] && continue
    if [ "$minutes" = 10 ]; then
      "$BIN" train "$DATA" --out "$field" --model "$model" --minutes 10 --clock cpu --force \
        > "$OUT/logs/${model}_10.train.log" 2>&1
    else
      "$BIN" train "$DATA" --out "$field" --resume --minutes 30 \
        > "$OUT/logs/${model}_30.train.log" 2>&1
    fi
    "$BIN" eval "$field" --data "$DATA" --out "$eval_dir" --every "$EVERY" --force \
      > "$OUT/logs/${model}_$minutes.eval.log" 2>&1
    echo "lego $model $minutes min: $(grep -o '"psnr": [0-9.]*' "$eval_dir/metrics.json" | head -1) $(grep -o '"ssim": [0-9.]*' "$eval_dir/metrics.json" | head -1)"
  done
done
