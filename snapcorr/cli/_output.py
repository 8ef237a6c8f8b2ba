"""What a command writes: its outputs checked before any work, its result written as the
output options say, and the lines that say what was written."""

from __future__ import annotations

from .._bundled import bundled_folder as _bundled_folder
from .._bundled import input_path as _input_path


def _check_outputs(outputs, inputs, overwrite, suffixes):
    """Refuse, before any work or any write, outputs that are, contain or lie in an input,
    that exist (without ``--overwrite``), have the wrong suffix or no folder to go in that can
    be written in (:func:`snapcorr.files.check_outputs`; bundled profiles are never replaced).

    ``outputs`` is ``{option: path}`` (``{"--out": args.out, "--plot": args.plot}``; a None
    path is not asked for): a refusal of a folder names the option."""
    from ..files.outputs import check_outputs

    check_outputs(list(outputs.values()), [_input_path(i) for i in inputs if i is not None],
                  overwrite=overwrite, suffixes=suffixes, protected=_bundled_folder(),
                  names=list(outputs))


#: The copies of the input a flat-field result keeps (``--no-input`` leaves them out).
RAW_COPIES = ("raw", "filter_white_raw")


def _without_input(ds, names, source):
    """``--no-input``: ``ds`` without the input's copy, saying where the input is."""
    present = [n for n in names if n in ds.variables]
    ds = ds.drop_vars(present)
    ds.attrs["input_left_out"] = f"{', '.join(present)} (--no-input); the input is {source}"
    return ds


def _write_result(args, ds, inputs, input_names, source):
    """Write ``ds`` to ``--out`` as the output options say; ``input_names`` are the input's
    copy, left out with ``--no-input``."""
    from ..cube import write_dataset

    if args.no_input:
        ds = _without_input(ds, input_names, source)
    return write_dataset(ds, args.out, overwrite=args.overwrite, inputs=inputs,
                         compression=args.compression,
                         store_derived=getattr(args, "store_derived", False),
                         dtype=getattr(args, "storage", None),
                         pack_range=getattr(args, "pack_range", None))


def _stored_type(args, computed):
    """The type the values are written in, as a summary line says it (``--dtype`` float16 or
    uint16 compute in float32)."""
    stored = getattr(args, "storage", None)
    if stored is None or stored == str(computed):
        return str(computed)
    return f"stored as {stored}{', CF-packed' if stored == 'uint16' else ''}, computed in " \
        f"{computed}"


def _masked_in(path):
    """``n_masked`` of a result just written (counted in the writing pass)."""
    from ..files.api import read_dataset

    with read_dataset(path, chunks={}) as ds:
        return int(ds["n_masked"])


def _quicklook(args, draw, what):
    """``--plot``: the quick look ``snapcorr.quicklook.<draw>`` of ``what``, if asked for."""
    if args.plot:
        from .. import quicklook

        getattr(quicklook, draw)(what, args.plot, overwrite=args.overwrite)
        print(f"wrote {args.plot}")


def _print_virtual(args, ds):
    """One line on the virtual bands of a result, if it has them."""
    if "virtual" in ds:
        wl = ds["virtual_wavelength"].values
        err = (f"; expected error up to {float(ds['virtual_stderr'].max()):.2g} (virtual_stderr)"
               if "virtual_stderr" in ds else "")
        print(f"virtual bands: {wl.size} from {wl.min():.1f} to {wl.max():.1f} nm, "
              f"{args.virtual_bands}{err}")

