"""What a writer checks before it writes anything: its targets, the inputs, the format's limits.

Every path a format writes (:func:`_targets`: an ENVI header and its data, a ``.npy`` and
its sidecar) is refused if it is or holds an input or a file that belongs to one
(:func:`_input_family`), and an existing one is replaced only with ``overwrite`` and only if
snapcorr wrote it (:func:`_written_by_snapcorr` looks for its mark; a Zarr store must also
hold nothing but Zarr metadata and arrays). :func:`_check_writable` checks what a format can
hold (dtype, ENVI's data-file names).
"""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path

import numpy as np

from .._io import file_kind, refuse_inputs
from .envi import _quiet_spectral
from .formats import _ENVI_DATA, _ENVI_EXTS, _sidecar
from .images import _EXR_EXACT, _TIFF_TYPES, open_image

#: Files a Zarr store holds at its top level besides its arrays and groups.
_ZARR_META = {"zarr.json", ".zgroup", ".zattrs", ".zmetadata"}


def _targets(fmt, path):
    """Every path a format writes: an ENVI header and its data, a ``.npy`` and its sidecar."""
    if fmt == "envi":
        return [path, path.with_suffix(".raw")]
    if fmt == "npy":
        return [path, _sidecar(path)]
    return [path]


def _input_family(inputs):
    """The inputs with the files that belong to them (an ENVI header's data file and the
    header of a data file, a ``.npy``'s sidecar)."""
    out = []
    for src in inputs:
        if src is None:
            continue
        p = Path(src)
        out.append(p)
        suffix = p.suffix.lower()
        if suffix == ".hdr":
            names = [*_ENVI_EXTS, ".bsq", ".bil", ".bip"]
            out += [c for e in names for c in {p.with_suffix(e), p.with_suffix(e.upper())}
                    if c != p and c.is_file()]
        elif suffix in _ENVI_DATA:
            out.append(p.with_suffix(".hdr"))
        elif suffix == ".npy":
            out.append(_sidecar(p))
    return out


def _is_mark(value):
    if isinstance(value, bytes):
        value = value.decode("utf-8", "replace")
    return isinstance(value, str) and value.startswith("snapcorr")


def _written_by_snapcorr(target, role):
    """``(True, "")`` if snapcorr wrote ``target`` (its mark is there), else ``(False, what
    was found)``."""
    if role == "zarr":
        return _zarr_is_ours(target)
    if role == "netcdf":
        import h5py

        try:
            with h5py.File(target, "r") as fh:
                attrs = dict(fh.attrs)
        except Exception:  # not HDF5 at all: h5py raises OSError and others
            return False, "a file that is not netCDF 4"
        if _is_mark(attrs.get("written_by")) or "snapcorr_version" in attrs:
            return True, ""
        return False, "a netCDF file without snapcorr's 'written_by' attribute"
    if role == "envi":
        try:
            with _quiet_spectral():
                from spectral.io import envi

                h = envi.read_envi_header(str(target))
        except Exception:
            return False, "a file that is not an ENVI header"
        if "snapcorr version" in h:
            return True, ""
        return False, "an ENVI header without snapcorr's 'snapcorr version' field"
    if role == "envi-data":
        hdr = target.with_suffix(".hdr")
        if not hdr.is_file():
            return False, f"a data file without its header {hdr.name}"
        ours, _ = _written_by_snapcorr(hdr, "envi")
        return (True, "") if ours else (False, f"the data of {hdr.name}, a header snapcorr "
                                               "did not write")
    if role in ("tiff", "exr"):
        import OpenImageIO as oiio

        inp = open_image(target)
        if inp is None:
            oiio.geterror()
            return False, f"a file that is not {role.upper()}"
        try:
            desc = inp.spec().getattribute("ImageDescription")
        finally:
            inp.close()
        try:
            meta = json.loads(desc) if isinstance(desc, str) else {}
        except ValueError:
            meta = {}
        if isinstance(meta, dict) and (_is_mark(meta.get("written_by"))
                                       or {"wavelength_nm", "dtype"} <= set(meta)):
            return True, ""
        return False, f"a {role.upper()} image snapcorr did not write"
    if role == "npy":
        side = _sidecar(target)
        if side.is_file():
            return _written_by_snapcorr(side, "sidecar")
        return False, f"a .npy file without snapcorr's sidecar {side.name}"
    if role == "sidecar":
        try:
            meta = json.loads(target.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, ValueError):
            return False, "a file that is not JSON"
        if isinstance(meta, dict) and _is_mark(meta.get("written_by")):
            return True, ""
        return False, "a JSON file snapcorr did not write"
    return False, "a file snapcorr does not recognise"


def _zarr_is_ours(target):
    strays = []
    for entry in os.scandir(target):
        if entry.name in _ZARR_META:
            continue
        if entry.is_dir(follow_symlinks=False) and any(
                (Path(entry.path) / m).is_file() for m in ("zarr.json", ".zarray", ".zgroup")):
            continue
        strays.append(entry.name)
    if strays:
        shown = ", ".join(sorted(strays)[:3]) + (", ..." if len(strays) > 3 else "")
        return False, f"a folder holding other things than a Zarr store ({shown})"
    attrs = None
    for meta, key in (("zarr.json", "attributes"), (".zattrs", None)):
        f = Path(target) / meta
        if f.is_file():
            try:
                doc = json.loads(f.read_text(encoding="utf-8"))
            except (OSError, UnicodeDecodeError, ValueError):
                return False, f"a folder whose {meta} is not JSON"
            attrs = doc.get(key, {}) if key else doc
            break
    if attrs is None:
        return False, "a folder that is not a Zarr store"
    if isinstance(attrs, dict) and (_is_mark(attrs.get("written_by"))
                                    or "snapcorr_version" in attrs):
        return True, ""
    return False, "a Zarr store without snapcorr's 'written_by' attribute"


_ROLES = {"envi": "envi", "tiff": "tiff", "exr": "exr", "netcdf": "netcdf", "zarr": "zarr",
          "npy": "npy"}


def _check_targets(fmt, targets, *, overwrite, inputs):
    """Refuse, before anything is written, a target that is or holds an input, or that exists
    (without ``overwrite``, or when snapcorr did not write it)."""
    refuse_inputs(targets, _input_family(inputs))
    for i, target in enumerate(targets):
        if not os.path.lexists(target):
            continue
        if not overwrite:
            raise FileExistsError(f"{target} exists; choose another name or pass "
                                  "overwrite=True (--overwrite)")
        try:
            st = os.stat(target)
        except OSError as err:
            raise ValueError(f"{target} exists but cannot be examined ({err.strerror}); "
                             "move it away or choose another name") from None
        role = _ROLES[fmt] if i == 0 else ("envi-data" if fmt == "envi" else "sidecar")
        directory = role == "zarr"
        if directory != stat.S_ISDIR(st.st_mode) or not (
                stat.S_ISDIR(st.st_mode) or stat.S_ISREG(st.st_mode)):
            raise ValueError(f"{target} exists and is {file_kind(st.st_mode)}; overwrite "
                             f"replaces only a {'Zarr store' if directory else 'file'} "
                             "snapcorr wrote: move it away or choose another name")
        ours, found = _written_by_snapcorr(target, role)
        if not ours:
            raise ValueError(f"{target} exists and is {found}; overwrite replaces only what "
                             "snapcorr wrote: move it away or choose another name")


def _check_writable(fmt, cube, path, interleave):
    """The format's own limits, before anything is written."""
    dtype = cube.dtype
    if fmt == "envi":
        from spectral.io import envi

        if interleave not in ("bsq", "bil", "bip"):
            raise ValueError(f"interleave must be bsq, bil or bip, got {interleave!r}")
        if dtype.char not in envi.dtype_to_envi:
            kind = "16-bit float" if dtype == np.float16 else str(dtype)
            raise ValueError(f"ENVI has no {kind} type; convert the cube "
                             "(cube.astype('float32')) or write .exr, .nc or .zarr")
        others = [path.with_suffix(e) for e in _ENVI_EXTS if e != ".raw"]
        others = [o for o in others if os.path.lexists(o) and not os.path.isdir(o)]
        if others:
            raise ValueError(f"{others[0]} exists next to {path.name}, and ENVI readers would "
                             f"take it as the header's data instead of {path.stem}.raw; move "
                             "it away or choose another name")
    elif fmt == "exr" and dtype not in _EXR_EXACT:
        raise ValueError(
            f"OpenEXR stores 16- and 32-bit floats, so a {dtype} cube would not come back "
            "unchanged; convert it (cube.astype('float32')) or write .nc, .zarr or .tif"
        )
    elif fmt == "tiff" and dtype not in _TIFF_TYPES:
        raise ValueError(f"snapcorr writes TIFF cubes as 8/16-bit integers or 16/32/64-bit "
                         f"floats, not {dtype}; convert it or write .nc or .zarr")
