#!/usr/bin/env python3
"""GTSAM 4.3 on one JSON Robot Log problem (COSMO-Bench), the reference of `cargo xtask bench cosmo`.

Three batch solves of all robots in one graph from the file's initialisation: Levenberg-Marquardt on every
factor, Levenberg-Marquardt on the labelled inliers only (an oracle), and GNC with the truncated least
squares loss (GTSAM's default for GncLMOptimizer) where the odometry and priors, and the loops the file does
not list as possibly wrong, are known inliers. Prints one JSON object: per solve and robot the position
RMSE against the ground truth without alignment (the priors fix each robot's frame), the seconds the solve
took, and for GNC the loops it weighed below 0.5 split by label.

Usage: cosmo_gtsam.py FILE.jrl
"""
import json
import sys
import time

import gtsam
import numpy as np


def pose3(entry):
    w, x, y, z = entry["rotation"]
    return gtsam.Pose3(gtsam.Rot3.Quaternion(w, x, y, z), gtsam.Point3(*entry["translation"]))


def read(path):
    with open(path) as file:
        data = json.load(file)

    def labelled(section):
        return {(robot, entry, factor) for robot, pairs in data[section].items() for entry, factor in pairs}

    outliers = labelled("outlier_factors")
    suspects = labelled("potential_outlier_factors")
    factors = []
    for robot, entries in data["measurements"].items():
        for entry_index, entry in enumerate(entries):
            for factor_index, factor in enumerate(entry["measurements"]):
                noise = gtsam.noiseModel.Gaussian.Covariance(np.array(factor["covariance"]).reshape(6, 6))
                tag = (robot, entry_index, factor_index)
                if factor["type"] == "PriorFactorPose3":
                    built = gtsam.PriorFactorPose3(factor["key"], pose3(factor["prior"]), noise)
                else:
                    built = gtsam.BetweenFactorPose3(factor["key1"], factor["key2"],
                                                     pose3(factor["measurement"]), noise)
                factors.append({"factor": built, "suspect": tag in suspects, "outlier": tag in outliers})
    initial = {p["key"]: pose3(p) for poses in data["initialization"].values() for p in poses}
    truth = {p["key"]: pose3(p) for poses in data["groundtruth"].values() for p in poses}
    return data["name"], factors, initial, truth


def graph_and_values(factors, initial):
    graph = gtsam.NonlinearFactorGraph()
    values = gtsam.Values()
    for item in factors:
        graph.add(item["factor"])
        for key in item["factor"].keys():
            if not values.exists(key):
                values.insert(key, initial[key])
    return graph, values


def position_rmse(values, truth):
    squared = {}
    for key in values.keys():
        if key in truth:
            error = values.atPose3(key).translation() - truth[key].translation()
            squared.setdefault(chr(key >> 56), []).append(float(error @ error))
    return {robot: float(np.sqrt(np.mean(errors))) for robot, errors in sorted(squared.items())}


def timed(solve):
    started = time.perf_counter()
    result = solve()
    return result, time.perf_counter() - started


def main():
    name, factors, initial, truth = read(sys.argv[1])
    out = {"name": name}
    for label, chosen in [("lm_all", factors), ("lm_inliers", [f for f in factors if not f["outlier"]])]:
        graph, values = graph_and_values(chosen, initial)
        result, seconds = timed(
            lambda: gtsam.LevenbergMarquardtOptimizer(graph, values, gtsam.LevenbergMarquardtParams()).optimize())
        out[label] = {"ate_m": position_rmse(result, truth), "s": seconds}
    graph, values = graph_and_values(factors, initial)
    params = gtsam.GncLMParams(gtsam.LevenbergMarquardtParams())
    params.setKnownInliers([index for index, f in enumerate(factors) if not f["suspect"]])
    optimizer = gtsam.GncLMOptimizer(graph, values, params)
    result, seconds = timed(optimizer.optimize)
    weights = optimizer.getWeights()
    dropped = [f for index, f in enumerate(factors) if f["suspect"] and weights[index] < 0.5]
    kept_outliers = [f for index, f in enumerate(factors) if f["outlier"] and weights[index] >= 0.5]
    out["gnc_tls"] = {
        "ate_m": position_rmse(result, truth),
        "s": seconds,
        "outliers_kept": len(kept_outliers),
        "inliers_dropped": sum(1 for f in dropped if not f["outlier"]),
    }
    print(json.dumps(out))


if __name__ == "__main__":
    main()
