#!/usr/bin/env python3
"""Peer for `cargo xtask bench odometry`: the reference KISS-ICP (Python package `kiss-icp`, C++ core) on
a sequence SKiD wrote as raw scans, one `NNNNNN.xyzt` file per scan (float32 x, y, z, time offset in
seconds since the scan stamp). Deskewing gets each point's time normalised over its scan, as KISS-ICP's
own dataloaders give it. Prints one JSON line: {"poses": [[16 floats row-major], ...], "ms": [...]}.

Usage: kiss_icp_run.py FOLDER MAX_RANGE_M THREADS
"""

import json
import sys
import time
from pathlib import Path

import numpy as np
from kiss_icp.config import load_config
from kiss_icp.kiss_icp import KissICP


def main():
    folder, max_range, threads = Path(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3])
    paths = sorted(folder.glob("*.xyzt"))
    scans = (np.fromfile(path, dtype=np.float32).reshape(-1, 4).astype(np.float64) for path in paths)
    first = np.fromfile(paths[0], dtype=np.float32).reshape(-1, 4)
    config = load_config(None)
    # Scans without per-point times (KITTI's .bin) cannot be deskewed: KISS-ICP normalises the times by
    # their span, which is zero there.
    config.data.deskew = bool(np.ptp(first[:, 3]) > 0)
    config.data.max_range = max_range
    config.data.min_range = 0.0
    config.mapping.voxel_size = max_range / 100.0
    config.registration.max_num_threads = threads
    odometry = KissICP(config)
    poses, times_ms = [], []
    for scan in scans:
        points, stamps = scan[:, :3], scan[:, 3]
        span = stamps.max() - stamps.min()
        normalised = (stamps - stamps.min()) / span if span > 0 else np.zeros_like(stamps)
        started = time.perf_counter()
        odometry.register_frame(points, normalised)
        times_ms.append((time.perf_counter() - started) * 1e3)
        poses.append(odometry.last_pose.reshape(-1).tolist())
    print(json.dumps({"poses": poses, "ms": times_ms}))


if __name__ == "__main__":
    main()
