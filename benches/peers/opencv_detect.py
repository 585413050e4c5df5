#!/usr/bin/env python3
"""OpenCV peer of `cliffwatch detect`: dark or bright round targets by findContours + fitEllipse.

Usage: python3 benches/peers/opencv_detect.py [--polarity dark|bright] IMAGE... > peer.jsonl

The pipeline a user would write with opencv-python-headless: grey decode, adaptive (local mean)
threshold, external contours, area / convexity / axis-ratio tests, fitEllipse on the contour
points. Writes JSON Lines like `cliffwatch detect` (centre of the top-left pixel is (0, 0)).
Install: pip install opencv-python-headless (benches/peers/run.sh does it).
"""
import json
import math
import sys
import time

import cv2


def detect(path, polarity, dmin, dmax):
    t0 = time.perf_counter()
    img = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    if img is None:
        raise ValueError(f"{path}: cannot read image")
    mode = cv2.THRESH_BINARY_INV if polarity == "dark" else cv2.THRESH_BINARY
    block = 2 * int(dmax) + 1
    bw = cv2.adaptiveThreshold(img, 255, cv2.ADAPTIVE_THRESH_MEAN_C, mode, block, 40)
    contours, _ = cv2.findContours(bw, cv2.RETR_LIST, cv2.CHAIN_APPROX_NONE)
    targets = []
    for c in contours:
        if len(c) < 8:
            continue
        area = cv2.contourArea(c)
        if area < math.pi / 4 * dmin * dmin or area > math.pi / 4 * dmax * dmax:
            continue
        hull = cv2.contourArea(cv2.convexHull(c))
        if hull <= 0 or area / hull < 0.9:
            continue
        (cx, cy), (a, b), _ = cv2.fitEllipse(c)
        if min(a, b) <= 0 or max(a, b) / min(a, b) > 3.0:
            continue
        per = cv2.arcLength(c, True)
        if 4 * math.pi * area / (per * per) < 0.6:
            continue
        targets.append({"col": cx, "row": cy, "diameter_px": math.sqrt(a * b)})
    h, w = img.shape
    return {
        "image": path,
        "width_px": w,
        "height_px": h,
        "polarity": polarity,
        "elapsed_ms": (time.perf_counter() - t0) * 1e3,
        "targets": targets,
    }


def main(argv):
    polarity, dmin, dmax, paths = "dark", 8.0, 64.0, []
    i = 0
    while i < len(argv):
        if argv[i] == "--polarity":
            polarity = argv[i + 1]
            i += 2
        elif argv[i] == "--min-diameter-px":
            dmin = float(argv[i + 1])
            i += 2
        elif argv[i] == "--max-diameter-px":
            dmax = float(argv[i + 1])
            i += 2
        else:
            paths.append(argv[i])
            i += 1
    status = 0
    for p in paths:
        try:
            print(json.dumps(detect(p, polarity, dmin, dmax)))
        except ValueError as e:
            print(e, file=sys.stderr)
            status = 1
    return status


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
