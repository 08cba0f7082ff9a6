#!/usr/bin/env bash
# Mining and edit fidelity on the scene suite (issues 4 and 5): for every scene with an edit
# script in scenes/edits/, take the field trained by scripts/quality_suite.sh, mine it
# against its ground truth (naming the mined instances after the ground-truth keys), compose
# the mined layout again from the same test cameras, and compose the edit (two moves, a
# quarter turn, a deletion, a duplication) against `synth --edited` of the same edit.
#
#   scripts/edit_fidelity.sh [MODEL] [SCENES...]
#
# MODEL: s or i (default s); the fields come from $SUITE/fields/SCENE_MODEL.safetensors
# (SUITE as for scripts/quality_suite.sh, default runs/suite; run that first). Output under
# runs/fidelity/ ($SUITE/fidelity for another suite; the synthesised scenes are always in
# runs/fidelity/data): data/SCENE (the scene synthesised with its edit), lib/SCENE_MODEL (the
# library), compose/SCENE_MODEL_{same,edit} and table.md. Finished steps are skipped, so the script can be stopped and started again.
# OWN=R passes `mine --own-patch-residual R` (default: the mine default 0, every instance
# keeps its own patch in the mined layout; 2: templates where they fit; inf: templates only)
# and suffixes the output names with _ownR.
# REFINE=N refines the mined library's templates for N iterations (`assetfield refine`, against
# the scene's training views) and composes with the refined templates-only layout; with
# OWN=inf, the table compares templates before and after refinement.
# Set BIN to use another binary (default target/release/assetfield, built if missing).
set -euo pipefail
cd "$(dirname "$0")/.."
MODEL=${1:-s}
shift $(( $# > 0 ? 1 : 0 ))
SCENES=("$@")
if [ ${#SCENES[@]} -eq 0 ]; then
  for f in scenes/edits/*.ron; do SCENES+=("$(basename "$f" .ron)"); done
fi
BIN=${BIN:-target/release/assetfield}
[ -x "$BIN" ] || cargo build --release --locked
SUITE=${SUITE:-runs/suite}
OUT=runs/fidelity
[ "$SUITE" = runs/suite ] || OUT="$SUITE/fidelity"
mkdir -p runs/fidelity/data
mkdir -p "$OUT/data" "$OUT/lib" "$OUT/compose" "$OUT/logs"
MINED_TAG=${MODEL}${OWN:+_own$OWN}
TAG=${MINED_TAG}${REFINE:+_ref$REFINE}
OWN_ARGS=()
[ -n "${OWN:-}" ] && OWN_ARGS=(--own-patch-residual "$OWN")

for scene in "${SCENES[@]}"; do
  field="$SUITE/fields/${scene}_$MODEL.safetensors"
  eval_json="$SUITE/eval/${scene}_$MODEL/metrics.json"
  if [ ! -f "$field" ] || [ ! -f "$eval_json" ]; then
    echo "== $scene: no trained field ($field); run scripts/quality_suite.sh first"
    continue
  fi
  data="runs/fidelity/data/$scene"
  [ -f "$data/edited/transforms_test.json" ] ||
    "$BIN" synth "scenes/$scene.ron" --edited "scenes/edits/$scene.ron" --out "$data" --force \
      > "$OUT/logs/${scene}.synth.log" 2>&1
  lib="$OUT/lib/${scene}_$MINED_TAG"
  [ -f "$lib/metrics.json" ] ||
    "$BIN" mine "$field" --out "$lib" --gt "$data/gt_layout.json" --gt-names "${OWN_ARGS[@]}" \
      --force > "$OUT/logs/${scene}_$MINED_TAG.mine.log" 2>&1
  if [ -n "${REFINE:-}" ]; then
    refined="$OUT/lib/${scene}_$TAG"
    [ -f "$refined/refine.json" ] ||
      "$BIN" refine "$lib" --data "$data" --out "$refined" --iters "$REFINE" --force \
        > "$OUT/logs/${scene}_$TAG.refine.log" 2>&1
    cp "$lib/metrics.json" "$refined/metrics.json"
    lib="$refined"
  fi
  same="$OUT/compose/${scene}_${TAG}_same"
  [ -f "$same/metrics.json" ] ||
    "$BIN" compose "$lib/layout.ron" --library "$lib" --views "$data" --metrics --out "$same" \
      --force > "$OUT/logs/${scene}_$TAG.same.log" 2>&1
  edit="$OUT/compose/${scene}_${TAG}_edit"
  [ -f "$edit/metrics.json" ] ||
    "$BIN" compose "$lib/layout.ron" --library "$lib" --edits "scenes/edits/$scene.ron" \
      --views "$data/edited" --metrics --planes --out "$edit" --force \
      > "$OUT/logs/${scene}_$TAG.edit.log" 2>&1 ||
    echo "== $scene: the edit did not compose (see $OUT/logs/${scene}_$TAG.edit.log)"
  echo "== $scene $TAG: $(grep -o '"f1": [0-9.]*' "$lib/metrics.json"), edited $(grep -o '"psnr": [0-9.]*' "$edit/metrics.json" 2>/dev/null | head -1)"
done

python3 - "$OUT" "$MODEL" "$TAG" "$SUITE" "${SCENES[@]}" <<'EOF' || echo "(python3 missing: see $OUT/*/metrics.json)"
import json, os, sys
out, model, tag, suite, scenes = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4], sys.argv[5:]
def load(p):
    return json.load(open(p)) if os.path.exists(p) else None
rows = ["| scene | field PSNR | recomposed | edited | edited - field | F1 | ARI | yaw median | yaw max | position |",
        "|---|---|---|---|---|---|---|---|---|---|"]
worst = None
fmt = lambda v, d=2: "-" if v is None else f"{v:.{d}f}"
for s in scenes:
    f = load(f"{suite}/eval/{s}_{model}/metrics.json")
    m = load(f"{out}/lib/{s}_{tag}/metrics.json")
    a = load(f"{out}/compose/{s}_{tag}_same/metrics.json")
    e = load(f"{out}/compose/{s}_{tag}_edit/metrics.json")
    if not (f and m):
        continue
    drop = (e["psnr"] - f["psnr"]) if e else None
    if drop is not None:
        worst = drop if worst is None else min(worst, drop)
    rows.append(f"| {s} | {fmt(f['psnr'])} | {fmt(a and a['psnr'])} | {fmt(e and e['psnr'])} | {fmt(drop)} | "
                f"{fmt(m['f1'], 3)} | {fmt(m['ari'], 3)} | {fmt(m.get('yaw_median_deg'))} | "
                f"{fmt(m.get('yaw_max_deg'), 1)} | {fmt(m.get('position_median'), 3)} |")
text = "\n".join(rows) + f"\n\nworst edited - field: {fmt(worst)} dB (target: >= -2)\n"
open(f"{out}/table_{tag}.md", "w").write(text)
print(text)
EOF
