#!/usr/bin/env python3
"""Peer for `cargo xtask bench io`: decodes every PointCloud2 of a bag with rosbags' AnyReader and numpy,
to the same per-point values SKiD produces (x, y, z, intensity, time offset, ring as float32 columns),
and prints one JSON line: {"runs_ms": [...], "points": N, "messages": M}.

Usage: rosbags_decode.py BAG TOPIC RUNS
"""

import json
import sys
import time
from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReader

NUMPY = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}


def decode(message):
    order = ">" if message.is_bigendian else "<"
    dtype = np.dtype({
        "names": [f.name for f in message.fields],
        "formats": [order + NUMPY[f.datatype] for f in message.fields],
        "offsets": [f.offset for f in message.fields],
        "itemsize": message.point_step,
    })
    points = np.frombuffer(message.data, dtype=dtype, count=message.width * message.height)
    columns = np.empty((len(points), 6), dtype=np.float32)
    columns[:, 0] = points["x"]
    columns[:, 1] = points["y"]
    columns[:, 2] = points["z"]
    columns[:, 3] = points["intensity"]
    columns[:, 4] = points["time"]
    columns[:, 5] = points["ring"]
    return columns[np.isfinite(columns[:, :3]).all(axis=1)]


def main():
    bag, topic, runs = Path(sys.argv[1]), sys.argv[2], int(sys.argv[3])
    runs_ms, points, messages = [], 0, 0
    for _ in range(runs):
        started = time.perf_counter()
        points, messages = 0, 0
        with AnyReader([bag]) as reader:
            connections = [c for c in reader.connections if c.topic == topic]
            for connection, _, raw in reader.messages(connections=connections):
                cloud = reader.deserialize(raw, connection.msgtype)
                points += len(decode(cloud))
                messages += 1
        runs_ms.append((time.perf_counter() - started) * 1e3)
    print(json.dumps({"runs_ms": runs_ms, "points": points, "messages": messages}))


if __name__ == "__main__":
    main()
