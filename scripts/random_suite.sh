#!/usr/bin/env bash
# Random scenes (issue 16): synthesise the dev or validation random scenes of
# scenes/validation_seeds.txt, train an S-AssetField on each, mine it against its ground
# truth and write a table (scene, seed, field PSNR, F1, ARI, yaw median / max).
#
#   SET=dev|validation scripts/random_suite.sh [BUDGET] [SEEDS...]
#
# SET: which list of scenes/validation_seeds.txt (default dev). Nobody tunes on the
# validation seeds: run them to measure, not to adjust. BUDGET: training budget per field
# (default 6000it: 6000 iterations, the same field on every machine; `Nmin` or a bare N
# for CPU-minutes, see scripts/budget.sh). SEEDS: a subset of the list (default: all of it).
# Output under $RANDOM_OUT (default runs/random_$SET): data/random_SEED (the dataset, with
# its scene.ron), fields/random_SEED_s.safetensors, eval/random_SEED_s, mining/random_SEED_s,
# mining_paper/random_SEED_s (`--preset paper`, the baseline) and table.md. Finished steps are skipped (delete a file or folder to redo it).
# Set BIN to use another binary (default target/release/assetfield, built if missing),
# MINE_ARGS to pass more flags to every `assetfield mine`, SYNTH_ARGS to `assetfield synth`
# (e.g. "--res 128").
set -euo pipefail
cd "$(dirname "$0")/.."
SET=${SET:-dev}
MINUTES=${1:-6000it}
source scripts/budget.sh
source scripts/mine.sh
budget_flags "$MINUTES"
shift $(( $# > 0 ? 1 : 0 ))
case "$SET" in
  dev|validation) ;;
  *) echo "SET must be dev or validation, got '$SET'" >&2; exit 2 ;;
esac
# the list is the line `SET: SEED SEED ...` of the seeds file
LIST=$(sed -e 's/#.*//' scenes/validation_seeds.txt | grep -E "^\s*$SET:" | sed -E "s/^\s*$SET://" | xargs | tr ' ' ,)
[ -n "$LIST" ] || { echo "no '$SET' list in scenes/validation_seeds.txt" >&2; exit 2; }
SEEDS=("$@")
[ ${#SEEDS[@]} -gt 0 ] || IFS=, read -r -a SEEDS <<< "$LIST"
for s in "${SEEDS[@]}"; do
  [[ ",$LIST," == *",$s,"* ]] || { echo "seed $s is not in the $SET list ($LIST)" >&2; exit 2; }
done
BIN=${BIN:-target/release/assetfield}
[ -x "$BIN" ] || cargo build --release --locked
OUT=${RANDOM_OUT:-runs/random_$SET}
read -r -a MINE_EXTRA <<< "${MINE_ARGS:-}"
read -r -a SYNTH_EXTRA <<< "${SYNTH_ARGS:-}"
mkdir -p "$OUT/data" "$OUT/fields" "$OUT/eval" "$OUT/mining" "$OUT/mining_paper" "$OUT/logs"

for seed in "${SEEDS[@]}"; do
  scene="random_$seed"
  data="$OUT/data/$scene"
  field="$OUT/fields/${scene}_s.safetensors"
  eval_dir="$OUT/eval/${scene}_s"
  lib="$OUT/mining/${scene}_s"
  [ -f "$data/transforms_test.json" ] ||
    "$BIN" synth --random "$seed" --out "$data" --force ${SYNTH_EXTRA[@]+"${SYNTH_EXTRA[@]}"} \
      > "$OUT/logs/$scene.synth.log" 2>&1 ||
    { echo "== $scene: synthesis failed (see $OUT/logs/$scene.synth.log)"; continue; }
  if [ ! -f "$field" ]; then
    echo "== $scene: training ($BUDGET_NAME)"
    "$BIN" train "$data" --out "$field" --model s ${BUDGET_FLAGS[@]+"${BUDGET_FLAGS[@]}"} --force \
      --discard-checkpoint > "$OUT/logs/$scene.train.log" 2>&1 ||
      { echo "== $scene: training failed (see $OUT/logs/$scene.train.log)"; continue; }
  fi
  [ -f "$eval_dir/metrics.json" ] ||
    "$BIN" eval "$field" --data "$data" --out "$eval_dir" --force > "$OUT/logs/$scene.eval.log" 2>&1 ||
    echo "== $scene: eval failed (see $OUT/logs/$scene.eval.log)"
  mine_presets "$BIN" "$field" "$data/gt_layout.json" "$lib" "$OUT/mining_paper/${scene}_s" \
    "$OUT/logs/$scene" "$scene" ${MINE_EXTRA[@]+"${MINE_EXTRA[@]}"}
done

python3 - "$OUT" "$SET" "$BUDGET_NAME" "${SEEDS[@]}" <<'PY' || echo "(python3 missing: see $OUT/eval/*/metrics.json and $OUT/mining/*/metrics.json)"
import json, os, sys
out, set_name, budget, seeds = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4:]
def load(p):
    return json.load(open(p)) if os.path.exists(p) else None
rows = [f"Random scenes, {set_name} seeds, S-AssetField, {budget} per field", "",
        "| scene | seed | categories | objects | units/m | field PSNR | F1 | ARI | yaw median / max (deg) | paper F1 | paper ARI |",
        "|---|---|---|---|---|---|---|---|---|---|---|"]
scores = []
for seed in seeds:
    scene = f"random_{seed}"
    synth = load(os.path.join(out, "data", scene, "synth.json")) or {}
    ev = load(os.path.join(out, "eval", f"{scene}_s", "metrics.json"))
    mi = load(os.path.join(out, "mining", f"{scene}_s", "metrics.json"))
    pa = load(os.path.join(out, "mining_paper", f"{scene}_s", "metrics.json"))
    pf1, pari = (f"{pa['f1']:.3f}", f"{pa['ari']:.3f}") if pa else ("-", "-")
    psnr = f"{ev['psnr']:.2f}" if ev else "-"
    if mi:
        ym, yx = mi.get("yaw_median_deg"), mi.get("yaw_max_deg")
        yaw = "-" if ym is None else f"{ym:.2f} / {yx:.1f}"
        f1, ari = f"{mi['f1']:.3f}", f"{mi['ari']:.3f}"
        scores.append((mi["f1"], mi["ari"], ym, pa["f1"] if pa else None, pa["ari"] if pa else None))
    else:
        f1 = ari = yaw = "-"
    cats = len(synth.get("categories", [])) or "-"
    objs = synth.get("instances", "-")
    upm = synth.get("units_per_metre")
    upm = "-" if upm is None else f"{upm:.3f}"
    rows.append(f"| `{scene}` | {seed} | {cats} | {objs} | {upm} | {psnr} | {f1} | {ari} | {yaw} | {pf1} | {pari} |")
if scores:
    mean = lambda xs: sum(xs) / len(xs) if xs else float("nan")
    yaws = sorted(y for _, _, y, _, _ in scores if y is not None)
    med = yaws[len(yaws) // 2] if yaws else float("nan")
    pf = [p for *_, p, _ in scores if p is not None]
    pa_ = [a for *_, a in scores if a is not None]
    rows.append(
        f"| **mean** ({len(scores)} scenes) | | | | | | {mean([s[0] for s in scores]):.3f} "
        f"(worst {min(s[0] for s in scores):.3f}) | {mean([s[1] for s in scores]):.3f} | "
        f"median of medians {med:.2f} | {mean(pf):.3f} | {mean(pa_):.3f} |"
    )
text = "\n".join(rows) + "\n"
open(os.path.join(out, "table.md"), "w").write(text)
print(text)
PY
