#!/usr/bin/env python3
"""Find random scenes whose layout holds a configuration, without rendering them.

    scripts/scan_seeds.py FIRST LAST [--category TEXT] [--max-ratio R] [--bin PATH]

For each seed in FIRST..LAST (LAST excluded), `assetfield synth --random SEED` lays the scene
out and writes its ground truth at a tiny resolution (16 pixels, 2 views: a tenth of a
second a seed); every object standing on another whose category contains TEXT is printed
when its support's footprint is at most R times its own (bird's-eye boxes): what covers most
of a small table. Example, the stem set of docs/results.md (lamps covering side tables):

    scripts/scan_seeds.py 3000 4400 --category lamp --max-ratio 2.5

A seed found this way is still a dev scene: build it like any other
(`BASIS_OUT=runs/stem SCENES="random:4077 blender:random:4077" BUDGETS=8000
scripts/mining_basis.sh build`).
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile


def area(o):
    a = o["bev_aabb"]
    return max(a[2] - a[0], 0.0) * max(a[3] - a[1], 0.0)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("first", type=int)
    ap.add_argument("last", type=int)
    ap.add_argument("--category", default="", help="a substring of the standing object's category")
    ap.add_argument("--max-ratio", type=float, default=2.5, help="support's box area over the object's, at most")
    ap.add_argument("--bin", default="target/release/assetfield", help="the assetfield binary")
    args = ap.parse_args()
    if not os.path.exists(args.bin):
        sys.exit(f"{args.bin} not found: build it with `cargo build --release` or pass --bin")
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "scene")
        for seed in range(args.first, args.last):
            cmd = [args.bin, "synth", "--random", str(seed), "--out", out, "--res", "16", "--views", "2",
                   "--test-views", "1", "--force"]
            r = subprocess.run(cmd, capture_output=True, text=True)
            if r.returncode != 0:
                last = (r.stderr.strip().splitlines() or ["no message"])[-1]
                print(f"seed {seed}: synth failed: {last}", file=sys.stderr)
                continue
            with open(os.path.join(out, "gt_layout.json")) as f:
                g = json.load(f)
            by_id = {o["id"]: o for o in g["instances"]}
            for o in g["instances"]:
                sup = by_id.get(o.get("supported_by"))
                if sup is None or args.category not in o["category"]:
                    continue
                ratio = area(sup) / max(area(o), 1e-12)
                if ratio <= args.max_ratio:
                    print(f"{seed} #{o['id']} {o['category']} on #{sup['id']} {sup['category']}: "
                          f"support / object area {ratio:.2f}", flush=True)


if __name__ == "__main__":
    main()
