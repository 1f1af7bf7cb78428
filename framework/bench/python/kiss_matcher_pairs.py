#!/usr/bin/env python3
"""Peer for the registration benchmarks: the reference KISS-Matcher (the authors' Python package
`kiss-matcher`, C++ core; Lim et al., ICRA 2025) on scan pairs SKiD wrote, one `NNNN_target.bin` and
`NNNN_source.bin` per pair (KITTI .bin: float32 x, y, z, intensity per point). The matcher runs with its own defaults for the
given voxel size, as its examples call it. Prints one JSON line per pair:
{"pair": N, "target_from_source": [16 floats row-major], "final_inliers": n, "rotation_inliers": n, "valid": b,
 "ms": wall-clock milliseconds of `estimate`}.

Usage: kiss_matcher_pairs.py FOLDER VOXEL_SIZE_M
"""

import json
import sys
import time
from pathlib import Path

import kiss_matcher
import numpy as np


def read_kitti_bin(path):
    points = np.fromfile(path, dtype=np.float32).reshape(-1, 4)[:, :3].astype(np.float64)
    return points[np.isfinite(points).all(axis=1)]


def main():
    folder, voxel = Path(sys.argv[1]), float(sys.argv[2])
    for target_path in sorted(folder.glob("*_target.bin")):
        index = int(target_path.name.split("_")[0])
        source_path = folder / f"{index:04d}_source.bin"
        target, source = read_kitti_bin(target_path), read_kitti_bin(source_path)
        matcher = kiss_matcher.KISSMatcher(kiss_matcher.KISSMatcherConfig(voxel))
        started = time.perf_counter()
        solution = matcher.estimate(source, target)
        elapsed_ms = (time.perf_counter() - started) * 1e3
        pose = np.eye(4)
        pose[:3, :3] = np.asarray(solution.rotation)
        pose[:3, 3] = np.asarray(solution.translation).reshape(3)
        record = {
            "pair": index,
            "target_from_source": pose.reshape(-1).tolist(),
            "final_inliers": int(matcher.get_num_final_inliers()),
            "rotation_inliers": int(matcher.get_num_rotation_inliers()),
            "valid": bool(solution.valid),
            "ms": elapsed_ms,
        }
        print(json.dumps(record), flush=True)


if __name__ == "__main__":
    main()
