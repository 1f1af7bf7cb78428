#!/usr/bin/env python3
"""Peers of `cargo xtask bench stages`, run in the same benchmark as SKiD's stages:

- `gicp TARGET.bin SOURCE.bin REPEATS`: small_gicp (Koide, `small-gicp` package) GICP on one thread with its
  own settings for this pair (0.25 m downsampling, 10 neighbours, 1 m correspondences), end to end from raw
  points (`small_gicp.align` on the numpy arrays), and split into `preprocess_points` for both clouds and
  `align` on the prepared ones.
- `lm GRAPH.g2o REPEATS`: GTSAM's Levenberg-Marquardt (default parameters) on a 3-D g2o graph, from the
  file's initial estimate and from GTSAM's own chordal initialisation (`InitializePose3`, timed with it).
- `gnc GRAPH.g2o REPEATS`: GTSAM's GNC with Levenberg-Marquardt (truncated least squares, default
  schedule), odometry edges (consecutive ids) given as known inliers, from the file's initial estimate;
  a 2-D or 3-D graph. (`cargo xtask bench pgo` runs it on its graphs with wrong loops.)
  Prints the loop edges it rejected (weight below 0.5) as `outliers`, `[from, to]` pairs.

Point files are KITTI .bin (float32 x, y, z, intensity). Each mode prints one JSON object: the wall-clock
milliseconds of every repetition, and the result (pose, iterations, final cost).
"""

import json
import sys
import time

import numpy as np


def read_kitti_bin(path):
    points = np.fromfile(path, dtype=np.float32).reshape(-1, 4)[:, :3].astype(np.float64)
    return points[np.isfinite(points).all(axis=1)]


def timed(work):
    started = time.perf_counter()
    value = work()
    return value, (time.perf_counter() - started) * 1e3


def gicp(target_path, source_path, repeats):
    import small_gicp

    target, source = read_kitti_bin(target_path), read_kitti_bin(source_path)
    settings = dict(downsampling_resolution=0.25, max_correspondence_distance=1.0, num_threads=1)
    end_to_end, preprocess, align = [], [], []
    result = None
    for _ in range(repeats + 1):
        result, ms = timed(lambda: small_gicp.align(target, source, registration_type="GICP", **settings))
        end_to_end.append(ms)
        (prepared, ms_prepare) = timed(
            lambda: (
                small_gicp.preprocess_points(target, downsampling_resolution=0.25, num_neighbors=10, num_threads=1),
                small_gicp.preprocess_points(source, downsampling_resolution=0.25, num_neighbors=10, num_threads=1),
            )
        )
        ((target_cloud, target_tree), (source_cloud, _)) = prepared
        _, ms_align = timed(
            lambda: small_gicp.align(
                target_cloud, source_cloud, target_tree, max_correspondence_distance=1.0, num_threads=1
            )
        )
        preprocess.append(ms_prepare)
        align.append(ms_align)
    # The first repetition warms caches and is dropped.
    return {
        "end_to_end_ms": end_to_end[1:],
        "preprocess_ms": preprocess[1:],
        "align_ms": align[1:],
        "iterations": int(result.iterations),
        "inliers": int(result.num_inliers),
        "target_from_source": np.asarray(result.T_target_source).reshape(-1).tolist(),
    }


def read_graph(path):
    import gtsam

    with open(path) as file:
        three_d = "VERTEX_SE3" in file.read()
    graph, initial = gtsam.readG2o(path, three_d)
    first = min(initial.keys())
    if three_d:
        noise = gtsam.noiseModel.Diagonal.Sigmas(np.full(6, 1e-6))
        graph.add(gtsam.PriorFactorPose3(first, initial.atPose3(first), noise))
    else:
        noise = gtsam.noiseModel.Diagonal.Sigmas(np.full(3, 1e-6))
        graph.add(gtsam.PriorFactorPose2(first, initial.atPose2(first), noise))
    return gtsam, graph, initial


def lm(path, repeats):
    gtsam, graph, initial = read_graph(path)
    rows = {}
    for init in ("file", "chordal"):
        times, result, iterations = [], None, 0
        for _ in range(repeats):

            def solve():
                start = initial if init == "file" else gtsam.InitializePose3.initialize(graph)
                optimizer = gtsam.LevenbergMarquardtOptimizer(graph, start, gtsam.LevenbergMarquardtParams())
                return optimizer.optimize(), optimizer.iterations()

            (result, iterations), ms = timed(solve)
            times.append(ms)
        rows[init] = {"ms": times, "iterations": int(iterations), "final_cost": float(graph.error(result))}
    return rows


def gnc(path, repeats):
    gtsam, graph, initial = read_graph(path)
    known = []
    loops = {}
    for index in range(graph.size()):
        keys = graph.at(index).keys()
        if len(keys) == 1 or abs(int(keys[1]) - int(keys[0])) == 1:
            known.append(index)
        else:
            loops[index] = [int(keys[0]), int(keys[1])]
    times, result, weights = [], None, None
    for _ in range(repeats):

        def solve():
            params = gtsam.GncLMParams(gtsam.LevenbergMarquardtParams())
            params.setKnownInliers(known)
            optimizer = gtsam.GncLMOptimizer(graph, initial, params)
            return optimizer.optimize(), optimizer.getWeights()

        (result, weights), ms = timed(solve)
        times.append(ms)
    outliers = [pair for index, pair in loops.items() if weights[index] < 0.5]
    return {"ms": times, "final_cost": float(graph.error(result)), "outliers": outliers}


def main():
    mode = sys.argv[1]
    if mode == "gicp":
        record = gicp(sys.argv[2], sys.argv[3], int(sys.argv[4]))
    elif mode == "lm":
        record = lm(sys.argv[2], int(sys.argv[3]))
    elif mode == "gnc":
        record = gnc(sys.argv[2], int(sys.argv[3]))
    else:
        sys.exit(f"unknown mode {mode}; expected gicp, lm or gnc")
    print(json.dumps(record), flush=True)


if __name__ == "__main__":
    main()
