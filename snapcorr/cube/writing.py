"""What a writer checks before it writes anything: its targets, the inputs, the format's limits.

Every path a format writes (:func:`_targets`: an ENVI header and its data, a ``.npy`` and
its sidecar) is refused if it is or holds an input or a file that belongs to one
(:func:`_input_family`), and an existing one is replaced only with ``overwrite`` and only if
snapcorr wrote it (:func:`_written_by_snapcorr` looks for its mark, which must name the file
and match it, :func:`_tie_mark`; a Zarr store must also hold nothing but Zarr metadata and
arrays). Each target's state is noted when it is checked: the write replaces only that.
:func:`_check_writable` checks what a format can hold (dtype, ENVI's data-file names).
"""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path

import numpy as np

from .._io import NotRegularFileError, file_kind, note_checked, read_regular, refuse_inputs
from .attrs import _mark_matches, _tied_mark
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


# -- the mark tied to the file ---------------------------------------------------------------
#
# A re-save by another program (xarray, Spectral Python) copies the attributes, snapcorr's mark
# among them. So the mark is tied, when the finished file is moved in (``_io._stamp``), to the
# name it is written as and to a digest (``_*_description``) of what the file holds (netCDF,
# Zarr: its attributes and variables) or of which files these are (ENVI pairs, ``.npy`` and
# sidecar: their inode numbers, which the move in keeps and a re-save or copy does not);
# overwrite replaces a file only if its mark names it and the digest still matches. A mark of
# an earlier version (plain ``snapcorr <version>``, or ``snapcorr_version`` alone) names no
# file and is refused.

#: The most read of a header, a sidecar or a Zarr metadata document.
_META_LIMIT = 8 << 20


def _plain(value):
    """An attribute value as h5py gives it, as plain Python for JSON."""
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if isinstance(value, np.ndarray):
        return [_plain(v) for v in value.tolist()]
    if isinstance(value, np.generic):
        return _plain(value.item())
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    return value


def _netcdf_description(fh):
    """What a netCDF-4 (HDF5) file holds, for the mark's digest: its root attributes but the
    mark, and every object's name, kind, shape, type and attribute names."""
    attrs = {}
    for key in fh.attrs:
        if key == "written_by":
            continue
        try:
            attrs[key] = _plain(fh.attrs[key])
        except Exception:  # a type h5py cannot read back: its type only
            attrs[key] = f"<{fh.attrs.get_id(key).dtype}>"
    objects = []

    def visit(name, obj):
        objects.append([name, type(obj).__name__, list(getattr(obj, "shape", None) or ()),
                        str(getattr(obj, "dtype", "")), sorted(obj.attrs.keys())])

    fh.visititems(visit)
    return {"attrs": attrs, "objects": sorted(objects)}


def _read_json(path):
    """The JSON document at ``path`` (a regular file, bounded), else None."""
    try:
        return json.loads(read_regular(path, _META_LIMIT))
    except (OSError, ValueError):  # NotRegularFileError is a ValueError
        return None


def _zarr_root(folder):
    """``(metadata file, its document, the attributes)`` of a Zarr store's root group (Zarr
    3: ``zarr.json``; 2: ``.zattrs``), else None."""
    for meta, key in (("zarr.json", "attributes"), (".zattrs", None)):
        f = Path(folder) / meta
        if os.path.lexists(f):
            doc = _read_json(f)
            if not isinstance(doc, dict):
                return f, None, None
            attrs = doc.get(key, {}) if key else doc
            return f, doc, attrs if isinstance(attrs, dict) else None
    return None


def _zarr_description(folder, attrs):
    """What a Zarr store holds, for the mark's digest: its root attributes but the mark, and
    each array's or group's name, shape, type and attribute names."""
    children = []
    for entry in sorted(os.scandir(folder), key=lambda e: e.name):
        if not entry.is_dir(follow_symlinks=False):
            continue
        meta = _read_json(Path(entry.path) / "zarr.json")
        if meta is None:
            meta = _read_json(Path(entry.path) / ".zarray") or {}
            meta["attributes"] = _read_json(Path(entry.path) / ".zattrs") or {}
        if not isinstance(meta, dict):
            meta = {}
        inner = meta.get("attributes")
        children.append([entry.name, meta.get("shape"), meta.get("data_type", meta.get("dtype")),
                         sorted(inner) if isinstance(inner, dict) else None])
    return {"attrs": {k: v for k, v in attrs.items() if k != "written_by"},
            "children": children}


#: The ENVI header field holding the mark tied to the header's name.
_ENVI_MARK = "snapcorr written by"


def _is_mark_line(line):
    key, eq, _ = line.partition("=")
    return bool(eq) and key.strip().lower() == _ENVI_MARK


def _inode(path):
    try:
        return os.lstat(path).st_ino
    except OSError:
        return None


def _envi_description(hdr):
    """What ties an ENVI pair's mark to the pair snapcorr moved in: the header's and the data
    file's inode numbers (a move in keeps them; a re-save by another program, or a copy, makes
    new files). Their text and data are not part of it: an edit in place keeps the pair
    snapcorr's."""
    return {"header_inode": _inode(hdr), "data_inode": _inode(Path(hdr).with_suffix(".raw"))}


def _npy_of(sidecar):
    """The ``.npy`` file of a sidecar ``cube.npy.json``."""
    return Path(sidecar).with_name(Path(sidecar).name[:-len(".json")])


def _sidecar_description(sidecar):
    """What ties a ``.npy`` sidecar's mark to the pair snapcorr moved in: the sidecar's and
    the ``.npy`` file's inode numbers (see :func:`_envi_description`)."""
    return {"sidecar_inode": _inode(sidecar), "npy_inode": _inode(_npy_of(sidecar))}


def _tie_mark(new, name):
    """Tie snapcorr's mark in the finished temporary ``new`` (a ``.nc`` file, ``.zarr``
    folder, ENVI header or ``.npy`` sidecar) to ``name``, the file it becomes, and to what it
    holds. A file without snapcorr's mark (or not of its format) is left as it is."""
    lower = name.lower()
    if lower.endswith(".nc"):
        import h5py

        if not (Path(new).is_file() and h5py.is_hdf5(new)):
            return
        with h5py.File(new, "r+") as fh:
            if _is_mark(fh.attrs.get("written_by")):
                fh.attrs["written_by"] = _tied_mark(name, _netcdf_description(fh))
    elif lower.endswith(".zarr"):
        root = _zarr_root(new) if Path(new).is_dir() else None
        if root is None or root[2] is None or not _is_mark(root[2].get("written_by")):
            return
        f, doc, attrs = root
        attrs["written_by"] = _tied_mark(name, _zarr_description(new, attrs))
        f.write_text(json.dumps(doc, indent=2), encoding="utf-8")
        consolidated = Path(new) / ".zmetadata"  # Zarr 2 keeps a copy of the attributes
        meta = _read_json(consolidated) if consolidated.is_file() else None
        if isinstance(meta, dict) and isinstance(meta.get("metadata"), dict) \
                and ".zattrs" in meta["metadata"]:
            meta["metadata"][".zattrs"] = attrs
            consolidated.write_text(json.dumps(meta, indent=2), encoding="utf-8")
    elif lower.endswith(".hdr"):
        try:
            text = Path(new).read_text(encoding="utf-8")
        except (UnicodeDecodeError, IsADirectoryError):
            return
        fields = [line.partition("=")[0].strip().lower() for line in text.splitlines()]
        if "snapcorr version" not in fields:
            return
        lines = [line for line in text.splitlines() if not _is_mark_line(line)]
        mark = _tied_mark(name, _envi_description(new))
        Path(new).write_text("\n".join([*lines, f"{_ENVI_MARK} = {mark}"]) + "\n",
                             encoding="utf-8")  # in place: the same file, the same inode
    elif lower.endswith(".npy.json"):
        try:
            meta = json.loads(Path(new).read_text(encoding="utf-8"))
        except (UnicodeDecodeError, ValueError, IsADirectoryError):
            return
        if isinstance(meta, dict) and _is_mark(meta.get("written_by")):
            meta["written_by"] = _tied_mark(name, _sidecar_description(new))
            Path(new).write_text(json.dumps(meta, indent=1), encoding="utf-8")


def _open_regular(target):
    """``target`` opened for reading as a binary file object, if it is a regular file (a
    FIFO opens without waiting and is refused), else :class:`NotRegularFileError`."""
    fd = os.open(target, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    mode = os.fstat(fd).st_mode
    if not stat.S_ISREG(mode):
        os.close(fd)
        raise NotRegularFileError(f"{target} is {file_kind(mode)}")
    return os.fdopen(fd, "rb")


def _written_by_snapcorr(target, role):
    """``(True, "")`` if snapcorr wrote ``target`` (its mark is there, naming this file, and
    matches what the file holds), else ``(False, what was found)``."""
    if role == "zarr":
        return _zarr_is_ours(target)
    if role == "netcdf":
        import h5py

        try:
            with _open_regular(target) as raw, h5py.File(raw, "r") as fh:
                mark = fh.attrs.get("written_by")
                if not _is_mark(mark) and "snapcorr_version" not in fh.attrs:
                    return False, "a netCDF file without snapcorr's 'written_by' attribute"
                return _mark_matches(mark, target, _netcdf_description(fh), "a netCDF file")
        except NotRegularFileError:
            return False, "not a regular file"
        except Exception:  # not HDF5 at all: h5py raises OSError and others
            return False, "a file that is not netCDF 4"
    if role == "envi":
        try:
            text = read_regular(target, _META_LIMIT).decode("utf-8", "replace")
        except (OSError, ValueError):
            return False, "a file that is not an ENVI header (or one too large to read)"
        lines = text.splitlines()
        if not lines or lines[0].strip() != "ENVI":
            return False, "a file that is not an ENVI header"
        fields = {}
        for line in lines[1:]:
            key, eq, value = line.partition("=")
            if eq:
                fields.setdefault(key.strip().lower(), value.strip())
        if "snapcorr version" not in fields and _ENVI_MARK not in fields:
            return False, "an ENVI header without snapcorr's 'snapcorr version' field"
        return _mark_matches(fields.get(_ENVI_MARK), target, _envi_description(target),
                             "an ENVI header")
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
        meta = _read_json(target)
        if meta is None:
            return False, "a file that is not JSON"
        if not (isinstance(meta, dict) and _is_mark(meta.get("written_by"))):
            return False, "a JSON file snapcorr did not write"
        return _mark_matches(meta["written_by"], target, _sidecar_description(target),
                             "a .npy sidecar")
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
    root = _zarr_root(target)
    if root is None:
        return False, "a folder that is not a Zarr store"
    f, doc, attrs = root
    if doc is None:
        return False, f"a folder whose {f.name} is not JSON (or not a regular file)"
    if attrs is None or not (_is_mark(attrs.get("written_by")) or "snapcorr_version" in attrs):
        return False, "a Zarr store without snapcorr's 'written_by' attribute"
    return _mark_matches(attrs.get("written_by"), target, _zarr_description(target, attrs),
                         "a Zarr store")


_ROLES = {"envi": "envi", "tiff": "tiff", "exr": "exr", "netcdf": "netcdf", "zarr": "zarr",
          "npy": "npy"}


def _check_targets(fmt, targets, *, overwrite, inputs):
    """Refuse, before anything is written, a target that is or holds an input, or that exists
    (without ``overwrite``, or when snapcorr did not write it). What each target is now is
    noted (:func:`snapcorr._io.note_checked`): the write replaces only that."""
    refuse_inputs(targets, _input_family(inputs))
    for target in targets:
        note_checked(target)
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
