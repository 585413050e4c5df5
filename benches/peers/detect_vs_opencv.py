#!/usr/bin/env python3
"""Times `cliffwatch detect` against the OpenCV peer (opencv_detect.py) over the same images in
the same run (each a fresh process: start-up and decoding included, alternated, median of N),
and scores both against PhotoModeler's marks (score_pm.py).

Usage: benches/peers/run.sh (installs opencv-python-headless, builds the release binary), or
  python3 benches/peers/detect_vs_opencv.py BINARY IMAGE_DIR PMEXPORT [N]
"""
import glob
import os
import statistics
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))


def timed(cmd):
    t0 = time.perf_counter()
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    return time.perf_counter() - t0, out


def main():
    binary, image_dir, pm = sys.argv[1:4]
    n = int(sys.argv[4]) if len(sys.argv) > 4 else 7
    images = sorted(glob.glob(os.path.join(image_dir, "*.JPG")) + glob.glob(os.path.join(image_dir, "*.jpg")))
    cw_cmd = [binary, "detect", *images]
    cv_cmd = [sys.executable, os.path.join(HERE, "opencv_detect.py"), "--polarity", "dark", *images]
    cw_t, cv_t = [], []
    for _ in range(n):
        t, cw_out = timed(cw_cmd)
        cw_t.append(t)
        t, cv_out = timed(cv_cmd)
        cv_t.append(t)
    cw, cv = statistics.median(cw_t), statistics.median(cv_t)
    print(f"{len(images)} images, median of {n} runs (wall clock, process start and decoding included):")
    print(f"  cliffwatch detect   {cw * 1e3:7.1f} ms  ({cw * 1e3 / len(images):.1f} ms/image)")
    print(f"  OpenCV peer         {cv * 1e3:7.1f} ms  ({cv * 1e3 / len(images):.1f} ms/image)")
    print(f"  ratio cliffwatch / OpenCV: {cw / cv:.2f}")
    for name, out in (("cliffwatch", cw_out), ("OpenCV", cv_out)):
        r = subprocess.run([sys.executable, os.path.join(HERE, "score_pm.py"), pm],
                           input=out, check=True, capture_output=True, text=True).stdout
        print(f"  {name:10s} {r.strip()}")


if __name__ == "__main__":
    main()
