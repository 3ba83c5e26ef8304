"""Time esim_py (ESIM's C++ simulator) on a folder of frames, for `evsim bench esim`.

    python run.py FRAMES TIMESTAMPS C_POS C_NEG LOG_EPS WIDTH HEIGHT COUNTS_OUT

Runs EventSimulator.generateFromFolder once (refractory period 0, log image on) and prints one
JSON line: {"seconds": wall time of the call, "events": count, "on": ON count}. The import and
the counting below are not timed. COUNTS_OUT ("-": none) gets the per-pixel ON and OFF counts as
little-endian uint32, shape (2, HEIGHT, WIDTH).
"""
import json
import sys
import time

import esim_py
import numpy as np


def main():
    frames, stamps, c_pos, c_neg, log_eps, width, height, counts_out = sys.argv[1:9]
    sim = esim_py.EventSimulator(float(c_pos), float(c_neg), 0.0, float(log_eps), True)
    start = time.perf_counter()
    events = sim.generateFromFolder(frames, stamps)
    seconds = time.perf_counter() - start
    on = events[:, 3] > 0
    if counts_out != "-":
        w, h = int(width), int(height)
        counts = np.zeros((2, h, w), dtype=np.uint32)
        x = events[:, 0].astype(np.int64)
        y = events[:, 1].astype(np.int64)
        np.add.at(counts[0], (y[on], x[on]), 1)
        np.add.at(counts[1], (y[~on], x[~on]), 1)
        counts.astype("<u4").tofile(counts_out)
    print(json.dumps({"seconds": seconds, "events": int(len(events)), "on": int(on.sum())}))


if __name__ == "__main__":
    main()
