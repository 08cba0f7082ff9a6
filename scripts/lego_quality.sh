#!/usr/bin/env bash
# Train S-AssetField and the TensoRF-VM baseline on the real lego scene for 10 minutes,
# evaluate, continue the same runs to 30 minutes, evaluate again.
#
#   scripts/lego_quality.sh [TEST_EVERY]
#
# TEST_EVERY: evaluate every n-th of the 200 test views (default 1 = all of them).
# Budgets use `--clock cpu` (time to quality; a busy machine gives a run the same CPU time
# but not quite the same compute). With ITERS=N1,N2 the two budgets are iteration counts
# instead (the same fields on every machine). Output under $LEGO_OUT (default runs/lego/);
# finished steps are skipped, so the script can be stopped and started again.
set -euo pipefail
cd "$(dirname "$0")/.."
EVERY=${1:-1}
DATA=${DATA:-../shared/data/nerf_synthetic_lego_400}
BIN=${BIN:-target/release/assetfield}
[ -x "$BIN" ] || cargo build --release --locked
OUT=${LEGO_OUT:-runs/lego}
MODELS=${MODELS:-s vm}
mkdir -p "$OUT/logs"
# both 10-minute runs first, then both continued to 30 minutes (or ITERS=first,second)
IFS=, read -r -a ITER_BUDGETS <<< "${ITERS:-}"
for minutes in 10 30; do
  budget=(--minutes "$minutes" --clock cpu)
  # a resumed run keeps the clock it started with
  [ "$minutes" = 30 ] && budget=(--minutes 30)
  if [ ${#ITER_BUDGETS[@]} -eq 2 ]; then
    [ "$minutes" = 10 ] && budget=(--iters "${ITER_BUDGETS[0]}") || budget=(--iters "${ITER_BUDGETS[1]}")
  fi
  for model in $MODELS; do
    field="$OUT/lego_$model.safetensors"
    eval_dir="$OUT/eval_${model}_$minutes"
    [ -f "$eval_dir/metrics.json" ] && continue
    if [ "$minutes" = 10 ]; then
      "$BIN" train "$DATA" --out "$field" --model "$model" "${budget[@]}" --force \
        > "$OUT/logs/${model}_10.train.log" 2>&1
    else
      "$BIN" train "$DATA" --out "$field" --resume "${budget[@]}" \
        > "$OUT/logs/${model}_30.train.log" 2>&1
    fi
    "$BIN" eval "$field" --data "$DATA" --out "$eval_dir" --every "$EVERY" --force \
      > "$OUT/logs/${model}_$minutes.eval.log" 2>&1
    echo "lego $model $minutes min: $(grep -o '"psnr": [0-9.]*' "$eval_dir/metrics.json" | head -1) $(grep -o '"ssim": [0-9.]*' "$eval_dir/metrics.json" | head -1)"
  done
done
