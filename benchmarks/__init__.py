"""Speed and accuracy benchmarks for snapcorr (``python -m benchmarks``)."""
