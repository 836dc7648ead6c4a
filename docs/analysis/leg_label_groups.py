#!/usr/bin/env python3
"""Score `quarry lidar --scans ... --out DIR` tracks against the leg-tracker labels, per group.

The recordings' labels (PROVENANCE.md) are every leg-sized cluster within +-15 deg and 5 m of
the laser, and `quarry lidar --legs` scores the mean of a scan's labels as "the person". When a
second moving object is in the wedge, that mean lies between the two. This script splits each
scan's labels into groups (single linkage, 0.8 m = leg_pair_dist) and reports:
  - scans whose labels form one group: matched within 0.5 m and RMSE, as `quarry lidar --legs`;
  - every group scored as a person of its own.
Scans before the first tracked row (the background warm-up) are left out.

usage: leg_label_groups.py LEGS.csv TRACKS.csv   (TRACKS.csv = DIR/tracks.csv)
"""
import collections
import csv
import math
import sys


def groups(legs, link=0.8):
    out = []
    for p in legs:
        hit = [k for k, g in enumerate(out) if any(math.dist(p, q) <= link for q in g)]
        if not hit:
            out.append([p])
            continue
        merged = out[hit[0]]
        merged.append(p)
        for k in sorted(hit[1:], reverse=True):
            merged.extend(out.pop(k))
    return out


def main(legs_csv, tracks_csv):
    labels = collections.defaultdict(list)
    for r in csv.DictReader(open(legs_csv)):
        labels[round(float(r["stamp_s"]), 6)].append((float(r["x_m"]), float(r["y_m"])))
    tracks = collections.defaultdict(list)
    for r in csv.DictReader(open(tracks_csv)):
        tracks[round(int(r["t_us"]) / 1e6, 6)].append((float(r["x"]), float(r["y"])))
    if not tracks:
        sys.exit("no track rows")
    first = min(tracks)
    one = matched_one = multi = matched_groups = n_groups = 0
    err_one, err_groups = [], []
    for t, legs in labels.items():
        if t < first:
            continue
        gs = groups(legs)
        near = lambda p: min((math.dist(p, q) for q in tracks.get(t, [])), default=math.inf)
        centre = lambda g: (sum(x for x, _ in g) / len(g), sum(y for _, y in g) / len(g))
        if len(gs) == 1:
            one += 1
            d = near(centre(legs))
            if d <= 0.5:
                matched_one += 1
                err_one.append(d)
        else:
            multi += 1
        for g in gs:
            n_groups += 1
            d = near(centre(g))
            if d <= 0.5:
                matched_groups += 1
                err_groups.append(d)
    rmse = lambda e: math.sqrt(sum(x * x for x in e) / len(e)) if e else float("nan")
    print(f"labelled scans {one + multi}: one group {one} (matched {matched_one}, "
          f"RMSE {rmse(err_one):.3f} m), more than one group {multi}")
    print(f"groups {n_groups}: matched {matched_groups} ({matched_groups / max(n_groups, 1):.3f}), "
          f"RMSE {rmse(err_groups):.3f} m")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
