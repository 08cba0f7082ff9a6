#!/usr/bin/env python3
"""Training iteration times of several builds, run in turn on one fixed state.

    scripts/iteration_times.py RUNS 'CMD A' 'CMD B' ...

Each CMD runs the example `iteration_times` of one build (see
crates/field/examples/iteration_times.rs), e.g.
    'target/release/examples/iteration_times ../shared/data/nerf_synthetic_lego_400 runs/lego_state.safetensors 12'
The commands run one after another, RUNS times over. This machine's noise comes in bursts,
so for each iteration the fastest of the RUNS runs is kept; the figure is the mean of those
over the iterations after the first (the first builds the occupancy grid).
"""
import shlex
import subprocess
import sys


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    runs, cmds = int(sys.argv[1]), sys.argv[2:]
    times = {c: [] for c in cmds}
    for _ in range(runs):
        for c in cmds:
            out = subprocess.run(shlex.split(c), capture_output=True, text=True, check=True)
            line = next(l for l in out.stdout.splitlines() if l.startswith("TIMES"))
            times[c].append([float(x) for x in line.split()[1:]])
    for c in cmds:
        t = times[c]
        best = [min(r[i] for r in t) for i in range(1, len(t[0]))]
        means = " ".join(f"{sum(r[1:]) / (len(r) - 1):.0f}" for r in t)
        print(f"{sum(best) / len(best):7.1f} ms per iteration (run means {means}): {c}")


if __name__ == "__main__":
    main()
