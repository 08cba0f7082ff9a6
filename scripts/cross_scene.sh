#!/usr/bin/env bash
# The cross-scene library (issue 18, paper Sec. 3.4 and Fig. 8) on two suite scenes that share
# assets: `library` (lamps on reading tables, chairs, bookshelves, plants) and `living_room`
# (lamps on low side tables, bookshelves, plants): the shared lamp stands at two heights.
#
#   scripts/cross_scene.sh [ITERS] [SCENE_A SCENE_B]
#
# SCENE_A, SCENE_B: names under scenes/, or random:SEED for `synth --random SEED` (the
# validation pair of the README is random:1001 random:1010). Output under $CROSS_OUT
# (default runs/cross).
#
# For each scene: synthesise it (256 x 256 views); train an S-AssetField alone; train both
# scenes together as S- and as I-AssetField (`train A B --out DIR`, ITERS iterations each,
# default 3000); evaluate every field on its test views (jointly against alone); mine every
# jointly trained field against its ground truth; merge the two libraries of each model,
# once as they are and once with `--regroup`, against both ground truths (metrics.json:
# cross_scene_ari). Writes runs/cross/table.md. Finished steps are skipped, so the script
# can be stopped and started again. BIN as in the other scripts.
set -euo pipefail
cd "$(dirname "$0")/.."
ITERS=${1:-3000}
A=${2:-library}
B=${3:-living_room}
BIN=${BIN:-target/release/assetfield}
[ -x "$BIN" ] || cargo build --release --locked
OUT=${CROSS_OUT:-runs/cross}
mkdir -p "$OUT/data" "$OUT/logs" "$OUT/alone" "$OUT/eval" "$OUT/lib"
# a scene of the suite, or random:SEED (its folders are named random_SEED)
source_of() { case "$1" in random:*) echo --random "${1#random:}" ;; *) echo "scenes/$1.ron" ;; esac; }
SRC_A=$(source_of "$A"); SRC_B=$(source_of "$B")
A=${A/:/_}; B=${B/:/_}
for pair in "$A|$SRC_A" "$B|$SRC_B"; do
  s=${pair%%|*}; read -r -a src <<< "${pair#*|}"
  [ -f "$OUT/data/$s/transforms_test.json" ] ||
    "$BIN" synth "${src[@]}" --res 256 --out "$OUT/data/$s" --force > "$OUT/logs/$s.synth.log" 2>&1
done
for s in "$A" "$B"; do
  f="$OUT/alone/${s}_s.safetensors"
  [ -f "$f" ] || "$BIN" train "$OUT/data/$s" --out "$f" --iters "$ITERS" --force \
    > "$OUT/logs/${s}_alone.train.log" 2>&1
done
for m in s i; do
  [ -f "$OUT/joint_$m/$B.safetensors" ] ||
    "$BIN" train "$OUT/data/$A" "$OUT/data/$B" --model "$m" --out "$OUT/joint_$m" --iters "$ITERS" --force \
      > "$OUT/logs/joint_$m.train.log" 2>&1
done
psnr() { python3 -c "import json,sys; print('%.2f' % json.load(open(sys.argv[1]))['psnr'])" "$1"; }
for s in "$A" "$B"; do
  for f in "alone/${s}_s" "joint_s/$s" "joint_i/$s"; do
    e="$OUT/eval/${f//\//_}"
    [ -f "$e/metrics.json" ] || "$BIN" eval "$OUT/$f.safetensors" --data "$OUT/data/$s" --out "$e" \
      > "$OUT/logs/${f//\//_}.eval.log" 2>&1
  done
done
for m in s i; do
  for s in "$A" "$B"; do
    l="$OUT/lib/${s}_$m"
    [ -f "$l/metrics.json" ] || "$BIN" mine "$OUT/joint_$m/$s.safetensors" --gt "$OUT/data/$s/gt_layout.json" \
      --gt-names --out "$l" --force > "$OUT/logs/${s}_$m.mine.log" 2>&1
  done
  for how in kept regroup; do
    flag=(); [ "$how" = regroup ] && flag=(--regroup)
    merged="$OUT/lib/merged_${m}_$how"
    [ -f "$merged/metrics.json" ] || "$BIN" library merge "$OUT/lib/${A}_$m" "$OUT/lib/${B}_$m" "${flag[@]}" \
      --gt "$OUT/data/$A/gt_layout.json" "$OUT/data/$B/gt_layout.json" --out "$merged" --force \
      > "$OUT/logs/merged_${m}_$how.log" 2>&1
  done
done
# one container, assets of both scenes: the library room as mined (S, own patches) with the
# living room's sofa `sofa_s` (mined from the other scene, same shared tensors) placed at
# MOVE_TO, against `synth` of the same layout from the library's test cameras
if [ "$A" = library ] && [ "$B" = living_room ]; then
  MOVE_TO=${MOVE_TO:-"-1.0, 1.1"}
  printf 'Scene(\n    base: "../../scenes/library.ron",\n    layout: [Instance(asset: "sofa", at: (%s), yaw: 90, name: "visitor")],\n)\n' "$MOVE_TO" \
    > "$OUT/library_with_sofa.ron"
  [ -f "$OUT/data_with_sofa/edited/transforms_test.json" ] ||
    "$BIN" synth "scenes/$A.ron" --res 256 --edited "$OUT/library_with_sofa.ron" --out "$OUT/data_with_sofa" --force \
      > "$OUT/logs/with_sofa.synth.log" 2>&1
  python3 - "$OUT" "$MOVE_TO" <<'PY'
import re, sys
out, at = sys.argv[1], sys.argv[2]
lib = open(f"{out}/lib/library_s/layout.ron").read().replace('path: "."', 'path: "lib/library_s"')
other = open(f"{out}/lib/living_room_s/layout.ron").read()
# the living room's instance named sofa_s, and the asset it uses
m = re.search(r'Instance\(\s*asset: "([^"]+)",\s*at: \([^)]*\),\s*(?:yaw: ([-0-9.]+),\s*)?name: "sofa_s"', other)
asset, yaw = m.group(1), m.group(2) or "0.0"
d = re.search(r'"%s": Asset\((.*?)\n        \),' % re.escape(asset), other, re.S).group(1)
d = d.replace('path: "."', 'path: "lib/living_room_s"')
lib = lib.replace("assets: {", 'assets: {\n        "visitor_sofa": Asset(%s\n        ),' % d, 1)
lib = lib.replace("layout: [", 'layout: [\n        Instance(asset: "visitor_sofa", at: (%s), yaw: %s, name: "visitor"),' % (at, yaw), 1)
open(f"{out}/compose_with_sofa.ron", "w").write(lib)
PY
  [ -f "$OUT/compose_with_sofa/metrics.json" ] ||
    "$BIN" compose "$OUT/compose_with_sofa.ron" --library "$OUT/lib/library_s" --views "$OUT/data_with_sofa/edited" \
      --metrics --out "$OUT/compose_with_sofa" --force > "$OUT/logs/compose_with_sofa.log" 2>&1
  [ -f "$OUT/compose_library/metrics.json" ] ||
    "$BIN" compose "$OUT/lib/library_s/layout.ron" --library "$OUT/lib/library_s" --views "$OUT/data/$A" \
      --metrics --out "$OUT/compose_library" --force > "$OUT/logs/compose_library.log" 2>&1
fi
{
  echo "| scene | S alone (dB) | S joint (dB) | I joint (dB) |"
  echo "|---|---|---|---|"
  for s in "$A" "$B"; do
    echo "| $s | $(psnr "$OUT/eval/alone_${s}_s/metrics.json") | $(psnr "$OUT/eval/joint_s_$s/metrics.json") | $(psnr "$OUT/eval/joint_i_$s/metrics.json") |"
  done
  echo
  echo "| model | merge | cross_scene_ari | categories (spanning scenes) | shared gt categories united | per scene F1 / ARI |"
  echo "|---|---|---|---|---|---|"
  for m in s i; do
    for how in kept regroup; do
      python3 - "$OUT/lib/merged_${m}_$how/metrics.json" "$m" "$how" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
scenes = ", ".join("%.3f / %.3f" % (s["f1"], s["ari"]) for s in m["per_scene"])
print("| %s | %s | %.3f | %d (%d) | %d of %d | %s |" % (sys.argv[2], sys.argv[3], m["cross_scene_ari"],
      m["categories"], m["categories_spanning_scenes"], m["shared_gt_categories_united"],
      m["shared_gt_categories"], scenes))
PY
    done
  done
  if [ -f "$OUT/compose_with_sofa/metrics.json" ]; then
    echo
    echo "library room recomposed (own patches): $(psnr "$OUT/compose_library/metrics.json") dB;" \
      "with the living room's sofa placed in it: $(psnr "$OUT/compose_with_sofa/metrics.json") dB against synth of the same layout"
  fi
} > "$OUT/table.md"
cat "$OUT/table.md"
