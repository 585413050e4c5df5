#!/usr/bin/env python3
"""Scores detections (JSON Lines of `cliffwatch detect` or opencv_detect.py on stdin) against
PhotoModeler's marks of dbat-camcal: found, extra, rms distance after one global offset.

Usage: cliffwatch detect IMAGES... | python3 benches/peers/score_pm.py PMEXPORT [--adjust CLIFFWATCH]
       python3 benches/peers/score_pm.py PMEXPORT --marks --adjust CLIFFWATCH

A mark is found when a detection lies within 3 px of it (PhotoModeler's (0.5, 0.5) pixel
convention is shifted to cliffwatch's (0, 0)); a detection more than 3 px from every mark is an
extra (unmarked dots, code segments and clutter alike).

With `--adjust`, the found centres (each named after its mark) go through `CLIFFWATCH adjust
--model central`: the self-calibrating adjustment of the detect tests (c, x0, y0, k1-k3, p1, p2
estimated from c = 7.4653 mm and no distortion, PhotoModeler's points as approximations, free
network, data snooping), and its sigma0 in px is printed. `--marks` scores PhotoModeler's own marks
(stdin unread): the reference sigma0 of the same adjustment.
"""
import json
import math
import os
import subprocess
import sys
import tempfile

PIXEL_MM = 7.25319 / 2272.0


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


def points(pm_path):
    """PhotoModeler's 3-D points (id, X, Y, Z): the 7-field lines after the last image's block,
    its position and their sigma (the first two) skipped."""
    lines = open(pm_path).read().splitlines()
    last = max(i for i, l in enumerate(lines) if l.lower().endswith(".jpg"))
    rows = [l.split() for l in lines[last + 1:] if len(l.split()) == 7][2:]
    return [(int(t[0]), float(t[1]), float(t[2]), float(t[3])) for t in rows]


def sigma0(cliffwatch, pm_path, named):
    """sigma0 (px), dof, dropped of the self-calibrating adjustment of `named`:
    {image name: [(point id, col, row)]}."""
    epoch = {
        "observed_at": "2004-08-25T12:00:00Z",
        "cameras": [{"id": "olympus", "c_mm": 7.4653,
                     "calibrate": ["c", "x0", "y0", "k1", "k2", "k3", "p1", "p2"],
                     "pixel_size_mm": PIXEL_MM, "width_px": 2272, "height_px": 1704}],
        "images": [{"id": n.rsplit(".", 1)[0], "camera": "olympus",
                    "observations": [{"point": f"P{i}", "col": c, "row": r} for i, c, r in obs]}
                   for n, obs in sorted(named.items())],
        "approx": [{"point": f"P{i}", "X": x, "Y": y, "Z": z} for i, x, y, z in points(pm_path)],
    }
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(epoch, f)
    try:
        out = subprocess.run([cliffwatch, "adjust", "--model", "central", f.name],
                             check=True, capture_output=True, text=True).stdout
    finally:
        os.unlink(f.name)
    r = json.loads(out)
    return r["sigma0_mm"] / PIXEL_MM, r["dof"], len(r["dropped"])


def main():
    pm = marks(sys.argv[1])
    cliffwatch = sys.argv[sys.argv.index("--adjust") + 1] if "--adjust" in sys.argv else None
    if "--marks" in sys.argv:
        s0, dof, dropped = sigma0(cliffwatch, sys.argv[1], pm)
        n = sum(len(v) for v in pm.values())
        print(f"PhotoModeler's marks: {n}  sigma0 {s0:.4f} px  dof {dof}  dropped {dropped}")
        return
    total = sum(len(v) for v in pm.values())
    found, extra, d = 0, 0, []
    named = {}
    ms = []
    for line in sys.stdin:
        r = json.loads(line)
        name = os.path.basename(r["image"])
        ms.append(r.get("elapsed_ms", 0.0))
        mk = pm.get(name, [])
        dets = [(t["col"], t["row"]) for t in r["targets"]]
        used = set()
        for mark_id, mc, mr in mk:
            best, bi = 3.0, None
            for i, (c, rr) in enumerate(dets):
                e = math.hypot(c - mc, rr - mr)
                if e < best:
                    best, bi = e, i
            if bi is not None:
                found += 1
                used.add(bi)
                named.setdefault(name, []).append((mark_id, dets[bi][0], dets[bi][1]))
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
    if cliffwatch:
        s0, dof, dropped = sigma0(cliffwatch, sys.argv[1], named)
        print(f"sigma0 {s0:.4f} px  dof {dof}  dropped {dropped}")


if __name__ == "__main__":
    main()
