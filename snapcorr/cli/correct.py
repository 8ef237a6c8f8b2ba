"""``snapcorr correct``: the corrected central wavelength of every pixel and band (Eq. 23)."""

from __future__ import annotations

import numpy as np

from .._names import CORRECTION_MODELS
from ._frames import _correct_input, _keep_flatfield_record
from ._options import (
    ORIGIN_HELP,
    OVERWRITE_HELP,
    SENSOR_HELP,
    _add_center,
    _add_output_options,
    _add_progress_options,
    _add_virtual_options,
    _check_storage_option,
    _check_virtual_options,
    _f_number,
    _lens,
    _origin_arg,
    _positive,
    _sensor,
    _source,
    add_command,
)
from ._output import RAW_COPIES, _check_outputs, _print_virtual, _quicklook, _write_result
from ._progress import _StageBar
from ._types import _path

#: Its line in ``snapcorr --help``, and the start of its own.
HELP = "corrected central wavelength of every pixel and band (Eq. 23)"

#: Its examples (its --help shows them; ``snapcorr --help`` shows all).
EXAMPLES = r"""
      snapcorr correct scene_ff.nc --lens my_lens.toml --sensor snapscan_vnir --f-number 1.4 \
          --out scene_corrected.nc --resample --plot scene_corrected.png
                                          per-pixel corrected wavelengths (Eq. 23)
      snapcorr correct scene_ff.nc --lens my_lens.toml --sensor sensor.toml --f-number 4 \
          --source cube --tolerance-pct 0.5 --out scene_corrected.nc
                                          ... with the model the scene's own spectrum needs
      snapcorr correct scene_ff.nc --lens my_lens.toml --sensor snapscan_vnir --f-number 1.4 \
          --harmonise --out scene_harmonised.nc
                                          ... and spectra with one response per band, the
                                          same for a material anywhere in the field
      snapcorr correct scene_ff.nc --lens my_lens.toml --sensor snapscan_vnir --f-number 2 \
          --resample --no-input --out scene.hdr
                                          ... as ENVI pairs for other tools (scene.hdr,
                                          scene_wavelength_corrected.hdr, scene_resampled.hdr,
                                          ...), without a copy of the input
      snapcorr correct mosaic_ff.nc --lens my_lens.toml --sensor imec_5x5_nir --f-number 2 \
          --virtual-bands angle-aware --out mosaic_corrected.nc
                                          ... and virtual bands recomputed for each pixel's
                                          angle behind the lens (or: vendor, fitted)
    """


def add_parser(subparsers):
    p = add_command(subparsers, "correct", HELP, EXAMPLES)
    p.add_argument("cube", type=_path, help="the cube (.hdr, .tif, .exr, .nc, .zarr, .npy), "
                   "ideally flat-fielded; or a 2-D mosaic frame with a mosaic --sensor")
    p.add_argument("--lens", required=True,
                   help="lens profile (.toml) or a bundled one (edmund_optics_16mm)")
    p.add_argument("--sensor", required=True, help=SENSOR_HELP)
    p.add_argument("--f-number", type=_f_number, required=True, metavar="F",
                   help="the f-number the cube was taken at")
    p.add_argument("--out", type=_path, required=True,
                   help="result: .nc or .zarr (everything, provenance in the attributes), or "
                   "STEM.hdr for ENVI pairs (STEM.hdr the input's values, "
                   "STEM_wavelength_corrected.hdr, STEM_resampled.hdr, ...)")
    _add_center(p, "optical centre in sensor pixels (default: the lens profile's, "
                   "converted to this pixel pitch, else the sensor's centre)")
    p.add_argument("--sensor-origin-px", type=_origin_arg, default=None, metavar="ROW,COL",
                   help=ORIGIN_HELP)
    p.add_argument("--method", default="auto", choices=["auto", *CORRECTION_MODELS],
                   help="the model, cheapest first (default: %(default)s, the cheapest "
                   "meeting the tolerance; harmonised = vignetted and --harmonise)")
    p.add_argument("--tolerance-nm", type=_positive, default=0.01, metavar="NM",
                   help="largest wavelength error allowed, nm (default: %(default)s)")
    p.add_argument("--source", default=None, metavar="SOURCE",
                   help="the scene's spectrum: solar, solar:astm-g173, "
                   "tungsten:TEMPERATURE_K, cube (the cube's mean spectrum) or a two-column "
                   "file; --method auto then takes the cheapest model whose signal error "
                   "stays below --tolerance-pct")
    p.add_argument("--tolerance-pct", type=_positive, default=None, metavar="PCT",
                   help="radiometric tolerance with --source, percent (default: 0.5)")
    p.add_argument("--resample", action="store_true",
                   help="also interpolate each spectrum onto the nominal wavelengths")
    p.add_argument("--harmonise", action="store_true",
                   help="also give every pixel one common response per band (the widest in "
                   "the field, or --target-fwhm-nm) on the nominal wavelengths: the same "
                   "material gives the same spectrum anywhere")
    p.add_argument("--target-fwhm-nm", type=_positive, default=None, metavar="NM",
                   help="with --harmonise: the common response's FWHM for every band (at "
                   "least the widest in the field)")
    _add_virtual_options(p)
    p.add_argument("--plot", type=_path, default=None, metavar="PNG",
                   help="quick look: a band image, the CRA and shift maps, a few pixels' "
                   "spectra at nominal and corrected wavelengths")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="dask.distributed scheduler to run on, e.g. tcp://host:8786 "
                   "(default: in-process threads)")
    _add_output_options(p, input_name="the input cube", derived=True, dtype=True)
    p.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    _add_progress_options(p)
    p.set_defaults(func=run)


def run(args):
    from ..correct import correct_cube
    from ..cube.derived import with_fwhm_table

    inputs = [args.cube, args.lens, args.sensor]
    _check_outputs({"--out": args.out, "--plot": args.plot}, inputs, args.overwrite,
                   [(".nc", ".zarr", ".hdr"), (".png",)])
    if args.out.suffix.lower() == ".hdr" and (args.compression != "auto" or args.store_derived):
        raise ValueError("an ENVI result is written plainly and whole: --compression and "
                         "--store-derived go with .nc or .zarr")
    _check_storage_option(args)
    if args.source is not None and args.method != "auto":
        raise ValueError("--source chooses the model: use it with --method auto")
    if args.tolerance_pct is not None and args.source is None:
        raise ValueError("--tolerance-pct applies to the scene budget: give --source too")
    if args.target_fwhm_nm is not None and not (args.harmonise or args.method == "harmonised"):
        raise ValueError("--target-fwhm-nm sets the common response of --harmonise: give "
                         "--harmonise (or --method harmonised) too")
    lens = _lens(args.lens)
    sensor = _sensor(args.sensor)
    _check_source_option(args, sensor)
    try:
        cube, mask = _correct_input(args, sensor)
    except ValueError:  # a result's image of other bands (virtual): refused as that first
        _refuse_a_result(args.cube, _result_image(args.cube))
        raise
    _refuse_a_result(args.cube, cube)
    method, provenance = args.method, {}
    if args.source is not None:  # the scene budget chooses the model
        from ..budget import recommend_model

        if args.source.strip().lower().startswith("cube:"):  # one pixel's: checked, named
            _source(args.source, cube)

        method, _, provenance = recommend_model(
            cube, sensor, args.f_number, lens, args.source,
            tolerance_pct=0.5 if args.tolerance_pct is None else args.tolerance_pct,
            center_rc=args.center_rc, sensor_origin_px=args.sensor_origin_px)
    _check_virtual_options(args, sensor)
    with _StageBar("correcting: chief-ray angles, models and tables", count=False):
        ds = correct_cube(cube, sensor, args.f_number, lens, method=method,
                          tolerance_nm=args.tolerance_nm, center_rc=args.center_rc,
                          sensor_origin_px=args.sensor_origin_px, resample=args.resample,
                          harmonise=args.harmonise, target_fwhm_nm=args.target_fwhm_nm,
                          mask=mask, virtual_bands=args.virtual_bands,
                          virtual_matrix=args.virtual_matrix,
                          virtual_wavelengths_nm=args.virtual_wavelengths,
                          virtual_fwhm_nm=args.virtual_fwhm_nm)
    ds.attrs.update({**provenance, "cube_file": str(args.cube), "lens_file": str(args.lens),
                     "sensor_file": str(args.sensor)})
    _keep_flatfield_record(args.cube, ds)
    if args.scheduler:
        from distributed import Client

        try:
            client = Client(args.scheduler, timeout="10s")
        except OSError as err:
            raise ValueError(f"cannot reach the dask scheduler at {args.scheduler}: {err}") \
                from None
        with client:  # progress: the cluster's dashboard
            written = _write_correction(args, ds, inputs, cube.name)
    else:
        with _StageBar(f"correcting, writing {args.out.name}"):
            written = _write_correction(args, ds, inputs, cube.name)
    if len(written) > 1:
        print("ENVI pairs (header and .raw) in " + f"{args.out.parent}: "
              + ", ".join(p.name for p in written))
    named = args.out if any(str(w) == str(args.out) for w in written) else (
        f"the corrected variables of {args.out.name} (not its input's copy: --no-input)")
    print(f"wrote {named}: {cube.shape[0]} x {cube.shape[1]} x {cube.shape[2]} cube, f/"
          f"{args.f_number:g}, method {ds.attrs['method']} ({ds.attrs['method_reason']}); "
          f"CRA up to {ds.attrs['cra_max_deg']:.2f} deg, optical centre row "
          f"{ds.attrs['optical_center_rc'][0]:g}, col {ds.attrs['optical_center_rc'][1]:g} "
          f"({ds.attrs['optical_center_source']})"
          + ("; resampled onto the nominal wavelengths" if args.resample else ""))
    ds = with_fwhm_table(ds)  # built by the write already
    if "fwhm_table" in ds:
        table = ds["fwhm_table"].values
        print(f"each pixel's band FWHM: {np.nanmin(table):.3g}-{np.nanmax(table):.3g} nm over "
              f"the field ({sensor.profile} filters of {np.min(sensor.fwhm_nm):.3g}-"
              f"{np.max(sensor.fwhm_nm):.3g} nm)")
    _print_virtual(args, ds)
    if "harmonised" in ds:  # asked for, or chosen by the scene budget
        w = ds["fwhm_harmonised"].values
        print(f"harmonised: one response per band, FWHM {np.nanmin(w):.3g}-{np.nanmax(w):.3g} "
              f"nm ({ds['fwhm_harmonised'].attrs['source']})")
        left_out = ds["harmonised"].attrs.get("not_harmonised", "none")
        if not left_out.startswith("none"):  # measured responses: the bands left NaN, and why
            print(f"harmonised: not harmonised (NaN): {left_out}")
    _quicklook(args, "plot_correction", ds)
    return 0


def _refuse_a_result(path, cube):
    """Refuse an image of a correction's result (``X_resampled.hdr``, a cube named
    ``resampled``...) by its file: its values no longer sit at one pixel's filters, and a
    command line cannot rename it, as the library's refusal says a Python caller may."""
    from ..correct.core import RESULT_NAMES

    if cube is None or cube.name not in RESULT_NAMES:
        return
    made_from = cube.attrs.get("cube_file")
    source = f" ({made_from!s:.200}, as the result records)" if made_from else ""
    raise ValueError(f"{path} holds {cube.name!r}, an image of a correction's result, not a "
                     f"cube to correct: correct the cube it was made from{source}")


def _result_image(path):
    """The cube of ``path`` read without the sensor's wavelengths (its own name and
    provenance), or None where it cannot be read so either."""
    from ..files.api import read_cube

    try:
        return read_cube(path, chunks="rows")
    except Exception:  # a second look inside an error's handler: any failure
        return None  # leaves the first error to be said, never a traceback of its own


def _check_source_option(args, sensor):
    """``--source`` lets the scene budget choose the model; the budget models only some filter
    shapes, and ``correct`` has no option to name another: said before the cube is read."""
    if args.source is None:
        return
    from ..budget import SIGNAL_PROFILES

    if args.source.split(":")[0].strip().lower() != "cube":  # the cube's: once it is read
        _source(args.source)
    if sensor.profile not in SIGNAL_PROFILES:
        raise ValueError(f"--source chooses the model from a scene budget, which does not model "
                         f"the {sensor.profile} filters of --sensor {args.sensor}: choose the "
                         "model with --method instead (snapcorr budget --profile compares the "
                         f"models for a {'/'.join(SIGNAL_PROFILES)} stand-in)")


def _write_correction(args, ds, inputs, cube_name):
    """``correct``'s result as ``--out`` asks: a .nc or .zarr, or ENVI pairs; the paths."""
    if args.out.suffix.lower() == ".hdr":
        from ..files.datasets import stored_as
        from ..files.envi_result import write_envi_result

        if args.no_input:
            ds.attrs["input_left_out"] = f"{cube_name} (--no-input); the input is {args.cube}"
        ds = stored_as(ds, args.storage, None, "envi")
        return write_envi_result(ds, args.out, overwrite=args.overwrite, inputs=inputs,
                                 include_input=not args.no_input, input_name=cube_name)
    return [_write_result(args, ds, inputs, [cube_name, *RAW_COPIES], args.cube)]

