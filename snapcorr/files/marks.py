"""The writer's mark: how snapcorr tells its own files from a user's.

Every file snapcorr writes carries its mark (:func:`writer_mark`, ``"snapcorr <version>"``):
netCDF and Zarr in ``written_by``, ENVI headers in ``snapcorr version``, ``.npy`` sidecars
and TIFF/EXR descriptions in their JSON, PNGs in ``Software``, TOMLs in their first line.
When the finished file is moved in (:func:`tie_mark`, called by
:func:`snapcorr.files.safety.atomic_write` and its siblings), the mark is tied to the name
it is written as and to what the file holds, ``snapcorr <version> as "<name>" (check
<digest>)`` (:func:`tied_mark`), so that a copy, or a file another program saved from it
with its attributes, is not taken for snapcorr's own. :func:`written_by_snapcorr` (PNG and
TOML) and :func:`_written_by_snapcorr` (cubes and results, by role) read it back for
``overwrite``.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import stat
import struct
import zlib
from pathlib import Path

import numpy as np

from .._validation import parse_json
from .reading import (
    NotRegularFileError,
    _found,
    _sidecar,
    file_kind,
    open_image,
    read_regular,
)

__all__ = ["MARK", "mark_matches", "tie_mark", "tied_mark", "untie_mark", "writer_mark",
           "written_by_snapcorr"]

#: What snapcorr writes into its own PNGs (``Software``) and TOMLs (the first line), so that
#: ``overwrite`` can tell them from a user's files.
MARK = "snapcorr"
_MARK = MARK

#: The most of a PNG read to find its mark, and of a TOML, a header or a JSON document.
_PNG_LIMIT = 64 << 20
_TEXT_LIMIT = 8 << 20
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_TIED_RE = re.compile(r'^snapcorr (\S+) as ("(?:[^"\\]|\\.)*") \(check ([0-9a-f]{32})\)$')


def _token(name, *parts):
    """The check of a mark: a digest of the name a file was written as and of what it holds
    (bytes, or anything JSON can describe), so that a copy under another name, an edit or a
    re-save by another program no longer matches."""
    h = hashlib.sha256(json.dumps(name).encode())
    for part in parts:
        if not isinstance(part, bytes | bytearray):
            part = json.dumps(part, sort_keys=True, ensure_ascii=True, default=str).encode()
        h.update(len(part).to_bytes(8, "little"))
        h.update(part)
    return h.hexdigest()[:32]


def tied_mark(name, token):
    """snapcorr's mark tied to the file name it is written as:
    ``snapcorr <version> as "<name>" (check <token>)``."""
    from .. import __version__

    return f"{MARK} {__version__} as {json.dumps(name)} (check {token})"


def untie_mark(value):
    """``(name, token)`` of a :func:`tied_mark`, else None (no mark, or a mark of an earlier
    version that names no file)."""
    if isinstance(value, bytes):
        value = value.decode("utf-8", "replace")
    m = _TIED_RE.match(value) if isinstance(value, str) else None
    if m is None:
        return None
    try:
        name = parse_json(m.group(2))
    except ValueError:
        return None
    return (name, m.group(3)) if isinstance(name, str) else None


def mark_matches(value, target, token, what):
    """``(True, "")`` if the mark ``value`` names ``target`` and its check is ``token``, else
    ``(False, what was found)``.

    Parameters
    ----------
    value : str or bytes or None
        The mark found in the file.
    target : str or Path
        The file it was found in.
    token : str
        The check the file's name and content give now (:func:`_token`).
    what : str
        The kind of file, for the message ("a netCDF file", ...).
    """
    tie = untie_mark(value)
    if tie is None:
        return False, (f"{what} with snapcorr's mark of an earlier version, which does not "
                       "name the file it was written as (or copied from one of snapcorr's "
                       "and re-saved by another program)")
    name, check = tie
    if name != Path(target).name:
        return False, (f"{what} with the mark snapcorr gave {name}, copied or saved under "
                       "this name")
    if check != token:
        return False, (f"{what} with snapcorr's mark, but not as snapcorr wrote it (a copy, "
                       "an edit, or a re-save by another program)")
    return True, ""


def _png_chunks(data):
    """``[(type, body), ...]`` of a PNG up to its first IDAT; ``None`` if it is not one."""
    if not data.startswith(_PNG_SIGNATURE):
        return None
    chunks, pos = [], len(_PNG_SIGNATURE)
    while pos + 8 <= len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        if pos + 12 + length > len(data):
            return None
        chunks.append((kind, data[pos + 8:pos + 8 + length]))
        pos += 12 + length
        if kind == b"IEND":
            return chunks
    return None


def _png_text(kind, body):
    """``(keyword, text)`` of a PNG text chunk (tEXt, zTXt, iTXt), else None."""
    try:
        key, _, rest = body.partition(b"\0")
        if kind == b"tEXt":
            return key.decode("latin-1"), rest.decode("latin-1")
        if kind == b"zTXt":
            d = zlib.decompressobj()
            text = d.decompress(rest[1:], 1 << 16)
            return key.decode("latin-1"), text.decode("latin-1")
        if kind == b"iTXt":
            flag, _method, rest = rest[0], rest[1], rest[2:]
            _lang, _, rest = rest.partition(b"\0")
            _tkey, _, text = rest.partition(b"\0")
            if flag:
                text = zlib.decompressobj().decompress(text, 1 << 16)
            return key.decode("latin-1"), text.decode("utf-8", "replace")
    except (IndexError, zlib.error, UnicodeDecodeError):
        return None
    return None


def _png_token(name, chunks):
    return _token(name, *[body for kind, body in chunks if kind in (b"IHDR", b"PLTE", b"IDAT")])


def _png_software(chunks):
    for kind, body in chunks:
        text = _png_text(kind, body) if kind in (b"tEXt", b"zTXt", b"iTXt") else None
        if text is not None and text[0] == "Software":
            return text[1]
    return None


def _chunk(kind, body):
    return struct.pack(">I", len(body)) + kind + body + struct.pack(
        ">I", zlib.crc32(kind + body) & 0xFFFFFFFF)


def _stamp_png(new, name):
    """Tie the ``Software`` mark of the finished PNG ``new`` to ``name`` and its image."""
    data = Path(new).read_bytes()
    chunks = _png_chunks(data)
    if chunks is None or not str(_png_software(chunks) or "").startswith(MARK):
        return  # not snapcorr's own PNG: left as it is
    text = tied_mark(name, _png_token(name, chunks)).encode("latin-1", "backslashreplace")
    out = [_PNG_SIGNATURE]
    for kind, body in chunks:
        found = _png_text(kind, body) if kind in (b"tEXt", b"zTXt", b"iTXt") else None
        if found is not None and found[0] == "Software":
            out.append(_chunk(b"tEXt", b"Software\0" + text))
        else:
            out.append(_chunk(kind, body))
    Path(new).write_bytes(b"".join(out))


def toml_mark(name, body):
    return f"# written by {tied_mark(name, _token(name, body.encode('utf-8')))}\n"


def written_by_snapcorr(path):
    """``(True, "")`` if the PNG or TOML at ``path`` carries snapcorr's mark naming this file
    (its name, and a check of its content), else ``(False, what it is)``.

    The file is read only if it is a regular file, and only so much of it: anything else is
    ``(False, what it is)``. Other kinds: ``(False, "a file of a kind snapcorr does not
    mark")``. A mark of an earlier version, which names no file, is not accepted: a copy of
    snapcorr's file under another name, or one edited since, carries it too.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".png", ".toml"):
        return False, "a file of a kind snapcorr does not mark"
    limit = _PNG_LIMIT if suffix == ".png" else _TEXT_LIMIT
    try:
        data = read_regular(path, limit)
    except NotRegularFileError:
        mode, found = _found(path) if os.path.lexists(path) else (None, "nothing")
        if mode is not None and stat.S_ISREG(mode):
            found = f"a file larger than the {limit >> 20} MiB snapcorr reads to find its mark"
        return False, found
    except OSError as err:
        return False, f"a file that cannot be read ({err.strerror or err})"
    if suffix == ".png":
        chunks = _png_chunks(data)
        if chunks is None:
            return False, "a file that is not a PNG image"
        software = _png_software(chunks)
        if not str(software or "").startswith(MARK):
            return False, "a PNG that snapcorr did not write (no 'snapcorr' Software mark)"
        return mark_matches(software, path, _png_token(path.name, chunks), "a PNG")
    text = data.decode("utf-8", "replace")
    first, _, body = text.partition("\n")
    if not first.startswith(f"# written by {MARK}"):
        return False, "a TOML file that snapcorr did not write"
    return mark_matches(first[len("# written by "):].rstrip("\r"), path,
                        _token(path.name, body.encode("utf-8")), "a TOML file")


def _check_content(path):
    """Refuse a target that is not a regular file or folder (a FIFO, device, socket, a link
    to nothing, followed through a link), and a PNG or TOML snapcorr did not write."""
    if not os.path.lexists(path):
        return
    suffix = Path(path).suffix.lower()
    mode, found = _found(path)
    marked = suffix in (".png", ".toml")
    if mode is None or not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)) or (
            marked and stat.S_ISDIR(mode)):
        raise ValueError(f"{path} exists and is {found}; overwrite replaces only a "
                         f"{'Zarr store' if suffix == '.zarr' else 'file'} snapcorr wrote: "
                         "move it away or choose another name")
    if not marked:
        return
    ours, found = written_by_snapcorr(path)
    if not ours:
        raise ValueError(f"{path} exists and is {found}; overwrite replaces only what "
                         "snapcorr wrote: move it away or choose another name")


def writer_mark():
    """The mark of the writer: ``"snapcorr <version>"``.

    A writer puts it in (``written_by``; ENVI headers: ``snapcorr version``); when the
    finished file is moved in, it is tied to the name it is written as and to what the file
    holds (:func:`_tied_mark`, by :func:`tie_mark`)."""
    from .. import __version__

    return f"{MARK} {__version__}"


def _tied_mark(name, description):
    """The mark tied to the file ``name`` and to ``description`` (what the file holds, as
    anything JSON can describe): ``snapcorr <version> as "<name>" (check <digest>)``."""
    return tied_mark(name, _token(name, description))


def _mark_matches(value, target, description, what):
    """``(True, "")`` if the mark ``value`` is :func:`_tied_mark` of ``target``'s name and
    ``description``, else ``(False, what was found)``; an earlier version's mark, which names
    no file, does not match."""
    return mark_matches(value, target, _token(Path(target).name, description), what)


#: Files a Zarr store holds at its top level besides its arrays and groups.
_ZARR_META = {"zarr.json", ".zgroup", ".zattrs", ".zmetadata"}


def _is_mark(value):
    if isinstance(value, bytes):
        value = value.decode("utf-8", "replace")
    return isinstance(value, str) and value.startswith("snapcorr")


# -- the mark tied to the file ---------------------------------------------------------------
#
# A re-save by another program (xarray, Spectral Python) copies the attributes, snapcorr's mark
# among them. So the mark is tied, when the finished file is moved in (:func:`tie_mark`), to
# the name it is written as and to a digest (``_*_description``) of what the file holds (netCDF,
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
        return parse_json(read_regular(path, _META_LIMIT))
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


def _tie_netcdf(new, name):
    import h5py

    if not (Path(new).is_file() and h5py.is_hdf5(new)):
        return
    with h5py.File(new, "r+") as fh:
        if _is_mark(fh.attrs.get("written_by")):
            fh.attrs["written_by"] = _tied_mark(name, _netcdf_description(fh))


def _tie_zarr(new, name):
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


def _tie_envi_header(new, name):
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


def _tie_sidecar(new, name):
    try:
        meta = parse_json(Path(new).read_text(encoding="utf-8"))
    except (UnicodeDecodeError, ValueError, IsADirectoryError):
        return
    if isinstance(meta, dict) and _is_mark(meta.get("written_by")):
        meta["written_by"] = _tied_mark(name, _sidecar_description(new))
        Path(new).write_text(json.dumps(meta, indent=1), encoding="utf-8")


#: Name ending -> how the mark in a finished file of that name is tied to it (the formats
#: whose mark is something a re-save would copy).
MARK_TIES = {".png": _stamp_png, ".nc": _tie_netcdf, ".zarr": _tie_zarr,
             ".hdr": _tie_envi_header, ".npy.json": _tie_sidecar}


def tie_mark(new, name):
    """Tie snapcorr's mark in the finished temporary ``new`` (a PNG, ``.nc`` file, ``.zarr``
    folder, ENVI header or ``.npy`` sidecar) to ``name``, the file it becomes, and to what it
    holds. A file without snapcorr's mark (or not of its format) is left as it is."""
    lower = name.lower()
    for ending, tie in MARK_TIES.items():
        if lower.endswith(ending):
            tie(Path(new), name)
            return


_tie_mark = tie_mark


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
            meta = parse_json(desc) if isinstance(desc, str) else {}
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
