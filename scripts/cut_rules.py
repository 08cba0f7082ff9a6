#!/usr/bin/env python3
"""Replay the grouping's dendrogram cut offline under several rules (issue 31).

    python3 scripts/cut_rules.py LIB [LIB ...]

Each LIB is a library that `assetfield mine --gt` wrote (mining.json holds the final
distance matrix, metrics.json which ground-truth category every matched detection is).
The script clusters each distance matrix with average linkage, cuts it by every rule below,
and scores the ARI over the matched detections, as `mine` does. It compares rules without
mining again; `mine` itself is the measurement of record (the fixed cut at the value the
libraries were mined with reproduces their ARI; a rule that moves the cut does not redo
what `mine` decides with the separation before the cut, the copies test included).

Rules: a fixed separation (0.12, 0.25); a multiple of the median distance from each object
to its nearest other object (the scene's own noise), alone and with 0.12 as a floor; and
the largest ratio between consecutive merge heights inside a band of heights.

Needs numpy, scipy and scikit-learn (`pip install numpy scipy scikit-learn`); not used by
the build or the tests.
"""
import json
import sys

import numpy as np
from scipy.cluster.hierarchy import fcluster, linkage
from scipy.spatial.distance import squareform
from sklearn.metrics import adjusted_rand_score


def load(lib):
    mining = json.load(open(f"{lib}/mining.json"))
    metrics = json.load(open(f"{lib}/metrics.json"))
    d = np.array(mining["distance_matrix"], dtype=float)
    np.fill_diagonal(d, 0.0)
    d = (d + d.T) / 2
    truth = {
        p["detection"]: p["gt_category"]
        for p in metrics["per_instance"]
        if p["gt_category"] is not None
    }
    return d, truth, metrics["ari"]


def nearest_median(d):
    off = d + np.eye(len(d)) * 1e9
    return float(np.median(off.min(axis=1)))


def fixed(t):
    # every merge strictly below t applied, as `mine`'s separation cut
    return lambda d, heights: t - 1e-9


def noise_multiple(k, floor=0.0):
    return lambda d, heights: max(floor, k * nearest_median(d))


def largest_gap(lo, hi):
    def rule(d, heights):
        best = None
        for j, h in enumerate(heights):
            below = heights[j - 1] if j > 0 else 0.0
            if h <= lo or below >= hi:
                continue
            ratio = h / max(below, 1e-6)
            if best is None or ratio > best[0]:
                best = (ratio, j)
        if best is None:
            return lo
        j = best[1]
        below = heights[j - 1] if j > 0 else 0.0
        return (below + heights[j]) / 2 if below > 0 else heights[j] - 1e-9

    return rule


RULES = {
    "fixed 0.12": fixed(0.12),
    "fixed 0.25": fixed(0.25),
    **{f"noise x{k}": noise_multiple(k) for k in (3, 5, 8, 10, 15)},
    **{f"max(0.12, noise x{k})": noise_multiple(k, 0.12) for k in (3, 5, 8)},
    **{f"gap in [{lo}, {hi}]": largest_gap(lo, hi) for lo, hi in ((0.12, 0.5), (0.1, 0.6), (0.15, 0.5))},
}


def ari(d, truth, rule):
    ids = sorted(truth)
    if len(d) < 2 or len(ids) < 2:
        return 1.0
    z = linkage(squareform(d, checks=False), "average")
    labels = fcluster(z, rule(d, np.sort(z[:, 2])), criterion="distance")
    return adjusted_rand_score([truth[i] for i in ids], [labels[i] for i in ids])


def main(libs):
    if not libs:
        sys.exit(__doc__)
    scores = {name: [] for name in RULES}
    for lib in libs:
        d, truth, mined = load(lib)
        row = []
        for name, rule in RULES.items():
            a = ari(d, truth, rule)
            scores[name].append(a)
            row.append(f"{a:.2f}")
        print(f"{lib}: mined ARI {mined:.3f}; " + " ".join(row))
    print()
    print("| rule | mean ARI | lowest | fields under 0.9 |")
    print("|---|---|---|---|")
    for name, s in scores.items():
        print(f"| {name} | {np.mean(s):.3f} | {np.min(s):.3f} | {sum(a < 0.9 for a in s)} |")


if __name__ == "__main__":
    main(sys.argv[1:])
