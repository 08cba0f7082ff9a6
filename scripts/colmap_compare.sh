#!/usr/bin/env bash
# A synthesised capture against itself through COLMAP (issue 33, item 5): the same photos
# trained with COLMAP's poses and with the render's exact ones, scored on the same held-out
# photos (every 8th by name), and mined against the ground truth in each field's frame.
#
#   scripts/colmap_compare.sh RENDER OUT [TRAIN_FLAGS...]
#
# RENDER: a `synth` dataset (its photos at a size COLMAP can match, e.g. --res 512).
# OUT: COLMAP project (OUT/colmap: images/ named SPLIT_r_K.png, sparse/0, txt/), the exact
# poses as a nerfstudio file (OUT/exact, trained in the scene's box padded as COLMAP's is),
# fields, evaluations and libraries. TRAIN_FLAGS go to both trainings (default:
# --downscale 4 --iters 1500 --appearance off). Needs Debian's
# colmap. COLMAP's exhaustive matching grows with the square of the photos: 200 photos took
# 22 minutes on 2 busy cores.
set -euo pipefail
cd "$(dirname "$0")/.."
[ $# -ge 2 ] || { echo "usage: $0 RENDER OUT [TRAIN_FLAGS...]" >&2; exit 2; }
R=$(realpath "$1"); O=$2; shift 2
FLAGS=("$@"); [ ${#FLAGS[@]} -gt 0 ] || FLAGS=(--downscale 4 --iters 1500 --appearance off)
BIN=${BIN:-target/release/assetfield}
[ -x "$BIN" ] || cargo build --release --locked
REPOSE=target/release/examples/repose
[ -x "$REPOSE" ] || cargo build --release --locked -p assetfield-tests --example repose
mkdir -p "$O"
C="$O/colmap"
if [ ! -f "$C/txt/images.txt" ]; then
  rm -rf "$C"; mkdir -p "$C/images" "$C/sparse"
  for s in train test; do for f in "$R/$s"/*.png; do cp "$f" "$C/images/${s}_$(basename "$f")"; done; done
  export QT_QPA_PLATFORM=offscreen
  colmap feature_extractor --database_path "$C/db" --image_path "$C/images" --ImageReader.single_camera 1 \
    --ImageReader.camera_model SIMPLE_RADIAL --SiftExtraction.max_num_features 4096 \
    --SiftExtraction.use_gpu 0 > "$O/colmap_extract.log" 2>&1
  colmap exhaustive_matcher --database_path "$C/db" --SiftMatching.use_gpu 0 > "$O/colmap_match.log" 2>&1
  colmap mapper --database_path "$C/db" --image_path "$C/images" --output_path "$C/sparse" > "$O/colmap_map.log" 2>&1
  mkdir -p "$C/txt"
  colmap model_converter --input_path "$C/sparse/0" --output_path "$C/txt" --output_type TXT > /dev/null
fi
# the render's exact poses for the images COLMAP registered, in name order (the same holdout)
python3 - "$R" "$C" "$O/exact" <<'PY'
import json, math, os, sys
render, colmap, out = sys.argv[1:4]
os.makedirs(out, exist_ok=True)
names = sorted(l.split()[-1] for l in open(os.path.join(colmap, 'txt/images.txt'))
               if not l.startswith('#') and len(l.split()) >= 10 and l.split()[-1].endswith('.png'))
poses, fov = {}, None
for split in ['train', 'test']:
    d = json.load(open(os.path.join(render, f'transforms_{split}.json')))
    fov = d['camera_angle_x']
    for f in d['frames']:
        poses[f"{split}_{os.path.basename(f['file_path'])}.png"] = f['transform_matrix']
from PIL import Image
w, h = Image.open(os.path.join(colmap, 'images', names[0])).size
fl = 0.5 * w / math.tan(0.5 * fov)
frames = [{'file_path': f'images/{n}', 'transform_matrix': poses[n]} for n in names]
json.dump({'fl_x': fl, 'fl_y': fl, 'cx': w / 2, 'cy': h / 2, 'w': w, 'h': h, 'frames': frames},
          open(os.path.join(out, 'transforms.json'), 'w'), indent=1)
link = os.path.join(out, 'images')
if not os.path.exists(link):
    os.symlink(os.path.abspath(os.path.join(colmap, 'images')), link)
PY
# the exact run's box: the scene's, padded by 5% of its extent on every side as COLMAP's box
# from the points is (BOX_PAD_SHARE in crates/data/src/align.rs); unpadded, the room's walls
# lie on the box's faces and the 200-photo walk lost 1.5 dB and 0.1 F1 at 256 pixels. The
# render's world stands on z = 0, so the box's bottom is the ground (--ground-under-box on),
# as it is for the COLMAP run levelled on its floor; the nerfstudio file cannot say so
box=$(python3 - "$R/synth.json" <<'PY'
import json, sys
lo, hi = json.load(open(sys.argv[1]))['scene_aabb']
pad = [0.05 * (b - a) for a, b in zip(lo, hi)]
print(','.join(f'{v:.4f}' for v in [a - p for a, p in zip(lo, pad)] + [b + p for b, p in zip(hi, pad)]))
PY
)
"$BIN" train "$O/exact" --out "$O/exact.safetensors" --model s --aabb="$box" --align-ground none \
  --background-map on --ground-under-box on --force --discard-checkpoint "${FLAGS[@]}" > "$O/exact.train.log" 2>&1
"$BIN" train "$C" --out "$O/colmap.safetensors" --model s --force --discard-checkpoint "${FLAGS[@]}" \
  > "$O/colmap.train.log" 2>&1
for k in exact colmap; do
  rm -rf "$O/$k.eval"
  "$BIN" eval "$O/$k.safetensors" --out "$O/$k.eval" > "$O/$k.eval.log" 2>&1
done
"$REPOSE" gt-colmap "$R" "$C" "$O/colmap.safetensors" "$O/colmap_gt.json" | tee "$O/fit.log"
"$BIN" mine "$O/exact.safetensors" --out "$O/exact_lib" --gt "$R/gt_layout.json" --force \
  > "$O/exact.mine.log" 2>&1 || echo "exact: mining failed (see $O/exact.mine.log)"
"$BIN" mine "$O/colmap.safetensors" --out "$O/colmap_lib" --gt "$O/colmap_gt.json" --force \
  > "$O/colmap.mine.log" 2>&1 || echo "colmap: mining failed (see $O/colmap.mine.log)"
for k in exact colmap; do
  echo "$k: $(grep -o 'PSNR [0-9.]* dB, SSIM [0-9.]*' "$O/$k.eval.log" | head -1 || true);" \
    "mining $(grep -o 'F1 [0-9.]*\|ARI [0-9.]*' "$O/$k.mine.log" | head -n 2 | tr '\n' ' ' || true)"
done
