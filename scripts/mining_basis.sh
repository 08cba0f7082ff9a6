#!/usr/bin/env bash
# The mining basis (issue 31): a fixed set of dev scenes, each trained at fixed iteration
# budgets (the same fields on every machine, however fast or busy, except that Blender's
# Cycles renders differ a little between machines), mined with the default
# detector and with `--preset paper`, scored against the ground truth. Every change to
# mining (or to the trainer, for mining's sake) is reported on the whole basis.
#
#   scripts/mining_basis.sh [build|mine|table|all]     (default all)
#
# build: synthesise the scenes (40 + 10 views at 256 x 256) and train an S field per scene
#        and budget, LANES scenes at a time (default 2); finished fields are skipped, so a
#        stopped build resumes. 43 min 44 s from nothing on an idle 2-core machine
#        (2026-12-06; one scene at a time: 53 min 19 s, 3 of them since saved by Blender).
# mine:  mine every field (default and paper presets) into $MINE_OUT, LANES fields at a
#        time; finished ones are skipped (delete $MINE_OUT to mine again). 75 s on an idle
#        2-core machine (one field at a time: 94 s; the same libraries).
# table: $MINE_OUT/table.md: F1, ARI and yaw per scene and budget, the paper preset beside,
#        and the robustness checks (F1 at a third of the budget within 0.1 of the full
#        budget's; no F1 under 0.5); $MINE_OUT/f1_budget.svg: F1 against the budget per scene.
#
# The scenes: suite scenes of every kind of ground (a room with walls, a floor, carpet,
# concrete, a street) with objects on tables, desks and pallets, and random dev scenes of
# scenes/validation_seeds.txt with a partial, a thick, a thin and an asphalt floor, walls, no floor,
# and unit scales from 0.9 to 1.9 units per metre, and scenes rendered by a second renderer
# (`blender:SCENE`: the scene's meshes rendered again by Blender's Cycles with soft shadows
# and its own shading, scripts/blender_render.py; needs Debian's `blender`). SCENES
# overrides the list: names of scenes/*.ron, random:SEED, blender:NAME or blender:random:SEED.
# BUDGETS: the iteration budgets (default "2000 6000": the demo's budget and a third of it).
# BASIS_OUT (default runs/basis): data/, fields/NAME_ITERS.safetensors, logs/.
# MINE_OUT (default $BASIS_OUT/mine): NAME_ITERS and NAME_ITERS_paper libraries, table.md.
# BIN: the binary (default target/release/assetfield, built if missing); MINE_ARGS: more
# flags for every default-preset `assetfield mine`. LANES: scenes built at once (default 2).
set -euo pipefail
SELF="$(cd "$(dirname "$0")" && pwd)/$(basename "$0")"
cd "$(dirname "$0")/.."
source scripts/mine.sh
WHAT=${1:-all}
case "$WHAT" in
  build|mine|table|all) ;;
  build-scene) [ $# -eq 2 ] || { echo "usage: $0 build-scene SCENE" >&2; exit 2; } ;;
  mine-field) [ $# -eq 3 ] || { echo "usage: $0 mine-field SCENE ITERS" >&2; exit 2; } ;;
  *) echo "usage: $0 [build|mine|table|all]" >&2; exit 2 ;;
esac
DEFAULT_SCENES="conference_room living_room office warehouse street_trees random:2 random:6 random:12 random:1003 blender:cafe blender:random:1001"
read -r -a SCENES <<< "${SCENES:-$DEFAULT_SCENES}"
read -r -a BUDGETS <<< "${BUDGETS:-2000 6000}"
OUT=${BASIS_OUT:-runs/basis}
MOUT=${MINE_OUT:-$OUT/mine}
BIN=${BIN:-target/release/assetfield}
[ -x "$BIN" ] || cargo build --release --locked
read -r -a MINE_EXTRA <<< "${MINE_ARGS:-}"
mkdir -p "$OUT/data" "$OUT/fields" "$OUT/logs" "$MOUT/logs"

name_of() { local n="${1/blender:/blender_}"; echo "${n/random:/random_}"; }

# synthesise SCENE (a suite name or random:SEED) into DIR, with EXTRA flags
synth_into() {
  case "$1" in
    random:*) "$BIN" synth --random "${1#random:}" --out "$2" --res 256 --force "${@:3}" ;;
    *) "$BIN" synth "scenes/$1.ron" --out "$2" --res 256 --force "${@:3}" ;;
  esac
}

# the data and every budget's field of one scene (its trainings one after another: the
# smaller budget is a field of its own, trained with its own schedule, not a snapshot)
build_scene() {
  local scene=$1 name data
  name=$(name_of "$scene"); data="$OUT/data/$name"
  if [ ! -f "$data/transforms_test.json" ]; then
    case "$scene" in
      blender:*)
        command -v blender > /dev/null ||
          { echo "== $name: needs Debian's blender (apt-get install blender)"; return 0; }
        synth_into "${scene#blender:}" "$data.src" --mesh > "$OUT/logs/$name.synth.log" 2>&1
        rm -rf "$data"
        blender -b --factory-startup -P scripts/blender_render.py -- "$data.src" "$data" \
          > "$OUT/logs/$name.blender.log" 2>&1
        rm -rf "$data.src" ;;
      *) synth_into "$scene" "$data" > "$OUT/logs/$name.synth.log" 2>&1 ;;
    esac
  fi
  for it in "${BUDGETS[@]}"; do
    local field="$OUT/fields/${name}_$it.safetensors" t0=$SECONDS
    [ -f "$field" ] && continue
    echo "== $name: training $it iterations"
    start_flag=(--force)
    [ -f "${field%.safetensors}.ckpt.safetensors" ] && start_flag=(--resume)
    "$BIN" train "$data" --out "$field" --model s --iters "$it" "${start_flag[@]}" \
      --discard-checkpoint > "$OUT/logs/${name}_$it.train.log" 2>&1
    echo "   $name $it: $((SECONDS - t0)) s"
  done
}

# LANES scenes at a time (default 2). The fields do not depend on it: the trainer's sums
# are formed in the same order on any number of threads (bit for bit, tested on
# `random_6`). On 2 cores two trainings at once train 10% more fields per hour than one
# with both cores: a lone run leaves 11% of them idle between its parallel parts (1500
# iterations of `random_6`: 27.7 s alone, 50.1 s for two at once). Scenes rendered by
# Blender go first (their renders make them the longest), the others in their order.
build() {
  local start=$SECONDS queue=()
  for scene in "${SCENES[@]}"; do [[ $scene == blender:* ]] && queue+=("$scene"); done
  for scene in "${SCENES[@]}"; do [[ $scene == blender:* ]] || queue+=("$scene"); done
  printf '%s\n' "${queue[@]}" |
    BIN=$BIN BASIS_OUT=$OUT BUDGETS="${BUDGETS[*]}" MINE_OUT=$MOUT \
      xargs -P "${LANES:-2}" -I{} "$SELF" build-scene {}
  echo "== build: $((SECONDS - start)) s"
}

# mine one scene's field at one budget with both presets
mine_field() {
  local scene=$1 it=$2 name gt field
  name=$(name_of "$scene"); gt="$OUT/data/$name/gt_layout.json"
  field="$OUT/fields/${name}_$it.safetensors"
  [ -f "$field" ] || { echo "== $name $it: no field (run build)"; return 0; }
  mine_presets "$BIN" "$field" "$gt" "$MOUT/${name}_$it" "$MOUT/${name}_${it}_paper" \
    "$MOUT/logs/${name}_$it" "$name $it" ${MINE_EXTRA[@]+"${MINE_EXTRA[@]}"}
}

# LANES fields at a time, as the build (mining's serial stages leave a core idle: the basis
# in 75 s against 94 s one field at a time, 2026-12-06)
mine() {
  local start=$SECONDS
  for scene in "${SCENES[@]}"; do
    for it in "${BUDGETS[@]}"; do printf '%s %s\n' "$scene" "$it"; done
  done |
    BIN=$BIN BASIS_OUT=$OUT BUDGETS="${BUDGETS[*]}" MINE_OUT=$MOUT MINE_ARGS="${MINE_ARGS:-}" \
      xargs -P "${LANES:-2}" -L1 "$SELF" mine-field
  echo "== mine: $((SECONDS - start)) s"
}

table() {
  local names=()
  for scene in "${SCENES[@]}"; do names+=("$(name_of "$scene")"); done
  python3 - "$MOUT" "${BUDGETS[*]}" "${names[@]}" <<'PY'
import json, os, sys
out, budgets, names = sys.argv[1], [int(b) for b in sys.argv[2].split()], sys.argv[3:]
def load(p):
    try:
        return json.load(open(p))
    except (OSError, ValueError):
        return None
def cell(m):
    if m is None:
        return "failed"
    yaw = m.get("yaw_median_deg")
    yaw = "-" if yaw is None else f"{yaw:.1f}"
    return f"{m['f1']:.3f} / {m['ari']:.3f} / {yaw}"
head = "| scene | " + " | ".join(f"{b} it: F1 / ARI / yaw" for b in budgets) + " | " + \
       " | ".join(f"paper {b} it: F1 / ARI" for b in budgets) + " |"
rows = [head, "|---|" + "---|" * (2 * len(budgets))]
sums = {b: [] for b in budgets}
psums = {b: [] for b in budgets}
problems = []
for n in names:
    ms = {b: load(os.path.join(out, f"{n}_{b}", "metrics.json")) for b in budgets}
    ps = {b: load(os.path.join(out, f"{n}_{b}_paper", "metrics.json")) for b in budgets}
    for b in budgets:
        sums[b].append(ms[b]["f1"] if ms[b] else 0.0)
        psums[b].append(ps[b]["f1"] if ps[b] else 0.0)
    pc = [f"{p['f1']:.3f} / {p['ari']:.3f}" if p else "failed" for p in ps.values()]
    rows.append(f"| {n} | " + " | ".join(cell(ms[b]) for b in budgets) + " | " + " | ".join(pc) + " |")
    f1 = {b: (ms[b]["f1"] if ms[b] else 0.0) for b in budgets}
    full, third = max(budgets), min(budgets)
    if f1[third] < f1[full] - 0.1:
        problems.append(f"{n}: F1 {f1[third]:.3f} at {third} it, {f1[full]:.3f} at {full} it")
    for b in budgets:
        if f1[b] < 0.5:
            problems.append(f"{n}: F1 {f1[b]:.3f} at {b} it")
mean = lambda v: sum(v) / len(v) if v else 0.0
rows.append("| mean | " + " | ".join(f"**{mean(sums[b]):.3f}**" for b in budgets) + " | " +
            " | ".join(f"{mean(psums[b]):.3f}" for b in budgets) + " |")
rows.append("")
rows.append("Robustness (F1 at the smallest budget within 0.1 of the largest's, no F1 under 0.5): " +
            ("holds on every scene." if not problems else "fails: " + "; ".join(problems) + "."))
text = "\n".join(rows) + "\n"
open(os.path.join(out, "table.md"), "w").write(text)
print(text)

# the picture: F1 against the budget per scene, the default detector solid, the paper dashed
W, H, L, B, T, R = 720, 420, 60, 50, 20, 200
xs = sorted(budgets)
def px(b):
    return L + (W - L - R) * (0.5 if len(xs) == 1 else (b - xs[0]) / (xs[-1] - xs[0]))
def py(f):
    return T + (H - T - B) * (1.0 - f)
palette = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
           "#7f7f7f", "#bcbd22", "#17becf", "#393b79", "#637939", "#8c6d31", "#843c39"]
svg = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" font-family="sans-serif" font-size="12">',
       f'<rect width="{W}" height="{H}" fill="white"/>']
for f in (0.0, 0.25, 0.5, 0.75, 0.9, 1.0):
    svg.append(f'<line x1="{L}" y1="{py(f):.1f}" x2="{W - R}" y2="{py(f):.1f}" stroke="#ddd"/>')
    svg.append(f'<text x="{L - 8}" y="{py(f) + 4:.1f}" text-anchor="end">{f:g}</text>')
for b in xs:
    svg.append(f'<text x="{px(b):.1f}" y="{H - B + 18}" text-anchor="middle">{b}</text>')
svg.append(f'<text x="{(L + W - R) / 2:.0f}" y="{H - 8}" text-anchor="middle">training iterations</text>')
svg.append(f'<text x="14" y="{(T + H - B) / 2:.0f}" transform="rotate(-90 14 {(T + H - B) / 2:.0f})" text-anchor="middle">detection F1</text>')
for i, n in enumerate(names):
    col = palette[i % len(palette)]
    for suffix, dash in (("", ""), ("_paper", ' stroke-dasharray="4 3"')):
        pts = []
        for b in xs:
            m = load(os.path.join(out, f"{n}_{b}{suffix}", "metrics.json"))
            pts.append((px(b), py(m["f1"] if m else 0.0)))
        d = " ".join(f"{x:.1f},{y:.1f}" for x, y in pts)
        svg.append(f'<polyline points="{d}" fill="none" stroke="{col}" stroke-width="2"{dash}/>')
        for x, y in pts:
            svg.append(f'<circle cx="{x:.1f}" cy="{y:.1f}" r="3" fill="{col}"/>')
    svg.append(f'<line x1="{W - R + 15}" y1="{T + 14 + 18 * i}" x2="{W - R + 35}" y2="{T + 14 + 18 * i}" stroke="{col}" stroke-width="2"/>')
    svg.append(f'<text x="{W - R + 40}" y="{T + 18 + 18 * i}">{n}</text>')
k = len(names)
svg.append(f'<text x="{W - R + 15}" y="{T + 26 + 18 * k}">solid: default</text>')
svg.append(f'<text x="{W - R + 15}" y="{T + 44 + 18 * k}">dashed: --preset paper</text>')
svg.append("</svg>")
open(os.path.join(out, "f1_budget.svg"), "w").write("\n".join(svg) + "\n")
PY
}

case "$WHAT" in
  build) build ;;
  build-scene) build_scene "$2" ;;
  mine-field) mine_field "$2" "$3" ;;
  mine) mine ;;
  table) table ;;
  all) build; mine; table ;;
esac
