#!/usr/bin/env bash
# Change detection values and mine the whole basis with them (issue 31: every change is
# reported on the whole basis). The values start from the `options.detect` of a library the
# basis was mined into with the defaults, a Python statement edits them (the dict `d`), and
# every basis field (and every suite field, when SUITE names a trained suite) is mined with
# `assetfield mine --detect-params`; the F1 means and every field that changed are printed
# against the default run.
#
#   scripts/mining_ablation.sh NAME 'PYTHON STATEMENT'
#   e.g. scripts/mining_ablation.sh rim_two 'd["unpack"]["rim_texels"] = 2'
#
# Needs the basis built and mined (scripts/mining_basis.sh all). BASIS_OUT, MINE_OUT and BIN
# as for scripts/mining_basis.sh; SUITE and RES as for scripts/mining_suite.sh (the suite's
# default-run libraries are read from $SUITE/mining); output in $ABLATION_OUT/NAME (default
# runs/ablation). Finished fields are skipped.
set -euo pipefail
cd "$(dirname "$0")/.."
[ $# -eq 2 ] || { echo "usage: $0 NAME 'PYTHON STATEMENT'" >&2; exit 2; }
NAME=$1 EDIT=$2
BASIS=${BASIS_OUT:-runs/basis}
MOUT=${MINE_OUT:-$BASIS/mine}
OUT=${ABLATION_OUT:-runs/ablation}/$NAME
BIN=${BIN:-target/release/assetfield}
RES=${RES:-400}
mkdir -p "$OUT"
base=$(ls "$MOUT"/*/mining.json 2> /dev/null | grep -v _paper/ | head -n 1) ||
  { echo "no mined basis in $MOUT: run scripts/mining_basis.sh all" >&2; exit 1; }
python3 - "$base" "$EDIT" "$OUT/params.json" << 'PY'
import json, sys
d = json.load(open(sys.argv[1]))["options"]["detect"]
exec(sys.argv[2])
json.dump(d, open(sys.argv[3], "w"), indent=1)
PY
fields=("$BASIS"/fields/*_[0-9]*[0-9].safetensors)
[ -n "${SUITE:-}" ] && fields+=("$SUITE"/fields/*_s.safetensors)
for f in "${fields[@]}"; do
  [ -f "$f" ] || continue
  n=$(basename "$f" .safetensors)
  case $f in
    "$BASIS"/*) gt=$BASIS/data/${n%_*}/gt_layout.json ;;
    *) gt=runs/suite/data_$RES/${n%_s}/gt_layout.json ;;
  esac
  [ -f "$OUT/$n/metrics.json" ] ||
    "$BIN" mine "$f" --out "$OUT/$n" --gt "$gt" --force --detect-params "$OUT/params.json" \
      > "$OUT/$n.log" 2>&1 || echo "== $n: mining failed (see $OUT/$n.log)"
done
python3 - "$OUT" "$MOUT" "${SUITE:-}" << 'PY'
import glob, json, os, sys
out, mout, suite = sys.argv[1:4]
refs = [(mout, "*_[0-9]*[0-9]")] + ([(suite + "/mining", "*_s")] if suite else [])
sums, changed = {}, []
for ref, pat in refs:
    for m in sorted(glob.glob(f"{ref}/{pat}/metrics.json")):
        n = os.path.basename(os.path.dirname(m))
        if n.endswith("_paper"):
            continue
        group = "suite" if n.endswith("_s") else n.rsplit("_", 1)[1] + " it"
        p = os.path.join(out, n, "metrics.json")
        new = json.load(open(p))["f1"] if os.path.exists(p) else 0.0
        old = json.load(open(m))["f1"]
        s = sums.setdefault(group, [0.0, 0.0, 0])
        s[0] += new; s[1] += old; s[2] += 1
        if abs(new - old) > 1e-3:
            changed.append(f"{n} {old:.3f} -> {new:.3f}")
for g, (new, old, k) in sorted(sums.items()):
    print(f"{g}: mean F1 {old / k:.3f} -> {new / k:.3f} ({k} fields)")
print("changed: " + ("; ".join(changed) if changed else "none"))
PY
