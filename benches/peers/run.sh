#!/usr/bin/env bash
# cliffwatch detect vs OpenCV's findContours + fitEllipse on dbat-camcal, same run.
# Installs the peer (opencv-python-headless from PyPI) if missing; builds the release binary.
set -euo pipefail
cd "$(dirname "$0")/../.."
DATA=${DATA:-../shared/data/real/dbat-camcal}
python3 -c 'import cv2' 2>/dev/null || python3 -m pip install --quiet opencv-python-headless
cargo build --release --quiet --bin cliffwatch
python3 benches/peers/detect_vs_opencv.py target/release/cliffwatch "$DATA/images" "$DATA/camcal-pmexport.txt" "${RUNS:-7}"
