#!/usr/bin/env bash
# Asset mining on the scene suite (issue 4): mine every field that scripts/quality_suite.sh
# trained, score it against the scene's ground truth, and write a per-scene table.
#
#   scripts/mining_suite.sh [MODELS] [SCENES...]
#
# MODELS: comma-separated subset of s,i (default s,i); the fields come from
# $SUITE/fields/SCENE_MODEL.safetensors (SUITE and RES as for quality_suite.sh, default
# runs/suite and 400):
# train them with an iteration budget (e.g. `scripts/quality_suite.sh 6000it s`) so that the
# mining figures do not depend on how fast or busy the machine was.
# Output under $SUITE/mining (runs/mining for the default suite): SCENE_MODEL (the library,
# layout.ron, pictures and metrics.json) and table.md. Finished scenes are skipped (delete
# the SCENE_MODEL folder to mine it again).
# Set BIN to use another binary (default target/release/assetfield, built if missing),
# MINE_ARGS to pass more flags to every `assetfield mine` (e.g. "--group-on voxels"), and
# MINING_OUT to write somewhere else (give both: scenes already mined in the output folder
# are skipped, whatever flags mined them).
set -euo pipefail
cd "$(dirname "$0")/.."
MODELS=${1:-s,i}
shift $(( $# > 0 ? 1 : 0 ))
SCENES=("$@")
if [ ${#SCENES[@]} -eq 0 ]; then
  for f in scenes/*.ron; do SCENES+=("$(basename "$f" .ron)"); done
fi
BIN=${BIN:-target/release/assetfield}
[ -x "$BIN" ] || cargo build --release --locked
SUITE=${SUITE:-runs/suite}
# the ground truth of the views the fields were trained on (RES as for quality_suite.sh)
DATA_ROOT=runs/suite/data
[ "${RES:-400}" = 400 ] || DATA_ROOT="runs/suite/data_$RES"
OUT=runs/mining
[ "$SUITE" = runs/suite ] || OUT="$SUITE/mining"
OUT=${MINING_OUT:-$OUT}
read -r -a EXTRA <<< "${MINE_ARGS:-}"
mkdir -p "$OUT/logs"

for scene in "${SCENES[@]}"; do
  for model in ${MODELS//,/ }; do
    field="$SUITE/fields/${scene}_$model.safetensors"
    gt="$DATA_ROOT/$scene/gt_layout.json"
    [ -f "$field" ] && [ -f "$gt" ] || continue
    lib="$OUT/${scene}_$model"
    [ -f "$lib/metrics.json" ] ||
      "$BIN" mine "$field" --out "$lib" --gt "$gt" --force ${EXTRA[@]+"${EXTRA[@]}"} > "$OUT/logs/${scene}_$model.log" 2>&1 ||
      echo "== $scene $model: mining failed (see $OUT/logs/${scene}_$model.log)"
  done
done

python3 - "$OUT" "$MODELS" "${SCENES[@]}" <<'EOF' || echo "(python3 missing: see $OUT/*/metrics.json)"
import json, os, sys
out, models, scenes = sys.argv[1], sys.argv[2].split(','), sys.argv[3:]
head = "| scene | " + " | ".join(f"{m.upper()} F1 | {m.upper()} ARI | {m.upper()} yaw median / max (deg)" for m in models) + " |"
rows = [head, "|---|" + "---|---|---|" * len(models)]
met = total = 0
for s in scenes:
    cells = []
    for m in models:
        p = os.path.join(out, f"{s}_{m}", "metrics.json")
        if not os.path.exists(p):
            cells += ["-", "-", "-"]
            continue
        r = json.load(open(p))
        ym, yx = r.get("yaw_median_deg"), r.get("yaw_max_deg")
        yaw = "-" if ym is None else f"{ym:.2f} / {yx:.1f}"
        cells += [f"{r['f1']:.3f}", f"{r['ari']:.3f}", yaw]
        total += 1
        met += int(r["f1"] >= 0.95 and r["ari"] >= 0.9 and ym is not None and ym <= 5)
    rows.append(f"| `{s}` | " + " | ".join(cells) + " |")
text = "\n".join(rows) + f"\n\n{met} of {total} fields meet all three targets (F1 >= 0.95, ARI >= 0.9, yaw median <= 5 degrees).\n"
open(os.path.join(out, "table.md"), "w").write(text)
print(text)
EOF
