#!/usr/bin/env python3
"""Scores detections (JSON Lines of `cliffwatch detect` or opencv_detect.py on stdin) against
PhotoModeler's marks of dbat-camcal: found, extra, rms distance after one global offset.

Usage: cliffwatch detect IMAGES... | python3 benches/peers/score_pm.py PMEXPORT

A mark is found when a detection lies within 3 px of it (PhotoModeler's (0.5, 0.5) pixel
convention is shifted to cliffwatch's (0, 0)); a detection more than 3 px from every mark is an
extra (unmarked dots, code segments and clutter alike).
"""
import json
import math
import os
import sys


def marks(pm_path):
    names, out = {}, {}
    with open(pm_path) as f:
        for line in f:
            t = line.split()
            if len(t) == 2 and t[1].lower().endswith(".jpg"):
                names[int(t[0])] = os.path.basename(t[1])
            elif len(t) == 6 and t[4] == "0.10000":
                out.setdefault(int(t[0]), []).append((int(t[1]), float(t[2]) - 0.5, float(t[3]) - 0.5))
    return {names[i]: v for i, v in out.items()}


def main():
    pm = marks(sys.argv[1])
    total = sum(len(v) for v in pm.values())
    found, extra, d = 0, 0, []
    ms = []
    for line in sys.stdin:
        r = json.loads(line)
        name = os.path.basename(r["image"])
        ms.append(r.get("elapsed_ms", 0.0))
        mk = pm.get(name, [])
        dets = [(t["col"], t["row"]) for t in r["targets"]]
        used = set()
        for _, mc, mr in mk:
            best, bi = 3.0, None
            for i, (c, rr) in enumerate(dets):
                e = math.hypot(c - mc, rr - mr)
                if e < best:
                    best, bi = e, i
            if bi is not None:
                found += 1
                used.add(bi)
                d.append((dets[bi][0] - mc, dets[bi][1] - mr))
        for c, rr in dets:
            if all(math.hypot(c - mc, rr - mr) > 3.0 for _, mc, mr in mk):
                extra += 1
    mx = sum(a for a, _ in d) / len(d)
    my = sum(b for _, b in d) / len(d)
    e = sorted(math.hypot(a - mx, b - my) for a, b in d)
    rms = math.sqrt(sum(x * x for x in e) / len(e))
    print(f"found {found}/{total}  extra {extra}  offset ({mx:+.3f}, {my:+.3f}) px  "
          f"rms {rms:.3f} px  median {e[len(e) // 2]:.3f} px  images {len(ms)}")


if __name__ == "__main__":
    main()
