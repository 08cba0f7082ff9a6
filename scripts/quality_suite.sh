#!/usr/bin/env bash
# Train and evaluate every scene of the suite with each model, and write a table like the
# paper's Table 1 (test PSNR / SSIM per scene and model).
#
#   scripts/quality_suite.sh [BUDGET] [MODELS] [SCENES...]
#
# BUDGET: training budget per run (default 10): `Nit` iterations (the same field on every
# machine), `Nmin` or a bare N CPU-minutes (`--clock cpu`: time to quality; runs on a busy
# machine get the same CPU time, though not quite the same compute), or `default` (30000
# iterations). MODELS: comma-separated subset of s,i,vm (default s,i,vm). SCENES: names
# under scenes/ (default: all). RES: the views' size (default 400; the issues' suite
# figures use 256).
# Output under $SUITE (default runs/suite): data/SCENE (synthesised views; another SUITE
# reuses runs/suite/data), fields/SCENE_MODEL.safetensors, eval/SCENE_MODEL/metrics.json,
# and table.md. Finished runs are skipped and stopped ones resume from their checkpoints, so
# the script can be stopped and started again (with the same BUDGET: a resumed run keeps
# the budget it started with unless --iters or --minutes raises it).
# Set BIN to use another binary (default target/release/assetfield, built if missing).
set -euo pipefail
cd "$(dirname "$0")/.."
MINUTES=${1:-10}
source scripts/budget.sh
budget_flags "$MINUTES"
MODELS=${2:-s,i,vm}
shift $(( $# > 2 ? 2 : $# ))
SCENES=("$@")
if [ ${#SCENES[@]} -eq 0 ]; then
  for f in scenes/*.ron; do SCENES+=("$(basename "$f" .ron)"); done
fi
BIN=${BIN:-target/release/assetfield}
[ -x "$BIN" ] || cargo build --release --locked
OUT=${SUITE:-runs/suite}
RES=${RES:-400}
DATA_ROOT=runs/suite/data
[ "$RES" = 400 ] || DATA_ROOT="runs/suite/data_$RES"
mkdir -p "$OUT/fields" "$OUT/eval" "$OUT/logs" "$DATA_ROOT"

for scene in "${SCENES[@]}"; do
  data="$DATA_ROOT/$scene"
  [ -f "$data/transforms_test.json" ] || "$BIN" synth "scenes/$scene.ron" --out "$data" --res "$RES" --force
  for model in ${MODELS//,/ }; do
    field="$OUT/fields/${scene}_$model.safetensors"
    eval_dir="$OUT/eval/${scene}_$model"
    if [ ! -f "$field" ]; then
      echo "== $scene $model: training ($BUDGET_NAME)"
      # a run stopped part way (Ctrl-C, a machine going away) continues from its checkpoint
      start=(--force)
      [ -f "${field%.safetensors}.ckpt.safetensors" ] && start=(--resume)
      "$BIN" train "$data" --out "$field" --model "$model" ${BUDGET_FLAGS[@]+"${BUDGET_FLAGS[@]}"} \
        "${start[@]}" --discard-checkpoint >> "$OUT/logs/${scene}_$model.train.log" 2>&1
    fi
    if [ ! -f "$eval_dir/metrics.json" ]; then
      "$BIN" eval "$field" --data "$data" --out "$eval_dir" --force \
        > "$OUT/logs/${scene}_$model.eval.log" 2>&1
    fi
    echo "== $scene $model: $(grep -o '"psnr": [0-9.]*' "$eval_dir/metrics.json" | head -1)"
  done
done

# the table: one row per scene, PSNR / SSIM per model, and the means
python3 - "$OUT" "$MODELS" "${SCENES[@]}" <<'EOF' 2>/dev/null || awk 'BEGIN{print "(python3 missing: see eval/*/metrics.json)"}' > "$OUT/table.md"
import json, sys, os
out, models, scenes = sys.argv[1], sys.argv[2].split(','), sys.argv[3:]
rows = ["| scene | " + " | ".join(f"{m.upper()} PSNR | {m.upper()} SSIM" for m in models) + " |",
        "|---|" + "---|---|" * len(models)]
sums = {m: [0.0, 0.0, 0] for m in models}
for s in scenes:
    cells = []
    for m in models:
        p = os.path.join(out, "eval", f"{s}_{m}", "metrics.json")
        if os.path.exists(p):
            r = json.load(open(p))
            cells += [f"{r['psnr']:.2f}", f"{r['ssim']:.4f}"]
            sums[m][0] += r['psnr']; sums[m][1] += r['ssim']; sums[m][2] += 1
        else:
            cells += ["-", "-"]
    rows.append(f"| {s} | " + " | ".join(cells) + " |")
cells = []
for m in models:
    n = sums[m][2]
    cells += [f"**{sums[m][0]/n:.2f}**", f"**{sums[m][1]/n:.4f}**"] if n else ["-", "-"]
rows.append("| mean | " + " | ".join(cells) + " |")
open(os.path.join(out, "table.md"), "w").write("\n".join(rows) + "\n")
EOF
cat "$OUT/table.md"
