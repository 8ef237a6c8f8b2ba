"""Speed and accuracy benchmarks for snapcorr (``python -m benchmarks``)."""

import csv


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
