"""Speed and accuracy benchmarks for snapcorr (``python -m benchmarks``)."""

import csv
import os
import time


def write_csv(path, rows):
    """Rows (dicts with the same keys) as a CSV file next to the charts."""
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def pyplot():
    """matplotlib.pyplot on the file-only backend (benchmarks run without a screen)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def cpu_seconds():
    """(CPU seconds all processes have used, of this process and its waited-for children,
    wall clock): Linux's ``/proc/stat``; None elsewhere."""
    try:
        with open("/proc/stat") as fh:
            busy = [int(v) for v in fh.readline().split()[1:]]
    except (OSError, ValueError):
        return None
    idle = busy[3] + busy[4]  # idle, iowait
    t = os.times()
    return ((sum(busy[:8]) - idle) / os.sysconf("SC_CLK_TCK"),
            t.user + t.system + t.children_user + t.children_system, time.perf_counter())


def others_share(start):
    """The share of the machine's CPUs other processes used since ``start``
    (:func:`cpu_seconds`)."""
    end = cpu_seconds()
    if start is None or end is None:
        return float("nan")
    busy, own, wall = (b - a for a, b in zip(start, end, strict=True))
    return max(busy - own, 0.0) / (wall * (os.cpu_count() or 1))
