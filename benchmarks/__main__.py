"""``python -m benchmarks [--quick]``: print speed and accuracy measured in one run."""

import argparse
import platform

import numpy as np

from snapcorr import __version__

from . import (
    calibration,
    calibration_circles,
    correct,
    demosaic,
    io_memory,
    mean_shift,
    output_size,
    pupil,
    pupil_model,
    scaling,
    speed_accuracy,
    stability,
    startup,
    stream,
    unknown_lens,
    virtual_bands,
)

parser = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__)
parser.add_argument("--quick", action="store_true", help="small sizes: a smoke run of seconds")
args = parser.parse_args()
print(f"snapcorr {__version__}, numpy {np.__version__}, Python {platform.python_version()}, "
      f"{platform.machine()}")
mean_shift.targets(mean_shift.run(quick=args.quick))
print()
calibration.full_size_time(quick=args.quick)
calibration.noise_sweep(quick=args.quick, write=not args.quick)
calibration.fnumber_sweep(quick=args.quick, write=not args.quick)
calibration_circles.noise_sweep(quick=args.quick, write=not args.quick)
calibration_circles.coverage_sweep(quick=args.quick, write=not args.quick)
calibration_circles.full_size_time(quick=args.quick)
unknown_lens.coverage(quick=args.quick, write=not args.quick)
pupil_model.run(quick=args.quick, write=not args.quick)
print()
correct.run(quick=args.quick)
print()
speed_accuracy.run(quick=args.quick, write=not args.quick)
print()
stability.run(quick=args.quick, write=not args.quick)
print()
scaling.run(quick=args.quick, write=not args.quick)
print()
io_memory.run(quick=args.quick, write=not args.quick)
print()
pupil.run(quick=args.quick, write=not args.quick)
print()
virtual_bands.run(quick=args.quick, write=not args.quick)
print()
demosaic.run(quick=args.quick, write=not args.quick)
print()
stream.run(quick=args.quick, write=not args.quick)
print()
startup.run(quick=args.quick, write=not args.quick)
print()
output_size.run(quick=args.quick, write=not args.quick)
if args.quick:
    print("(quick mode: sizes are too small for the rates to be representative)")
