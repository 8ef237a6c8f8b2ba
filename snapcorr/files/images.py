"""TIFF and OpenEXR cubes and frames, read and written through OpenImageIO.

A TIFF holds one page with a channel per band, or one single-channel page per band; an
OpenEXR the spectral layout of Fichet et al. 2021 (``S0.<nm>nm`` emissive, ``T.<nm>nm``
reflective channels). snapcorr keeps a cube's metadata as JSON in the image description
(:func:`_description`). Images are read whole, in memory.
"""

from __future__ import annotations

import json
import math
import re

import numpy as np

from .._validation import WAVELENGTH_NM_RANGE, check_wavelengths_nm, parse_json, shown
from ..cube.model import POSITION_DIMS
from .attrs import _one_line
from .reading import open_image
from .safety import atomic_write
from .storage import FileFormat, _File

__all__ = ["open_image"]


#: Cube names written as OpenEXR reflective channels (``T.<nm>nm``); others are emissive.
_REFLECTIVE = ("reflectance", "transmittance")
#: dtypes an OpenEXR float channel holds exactly (float32 has a 24-bit significand).
_EXR_EXACT = tuple(np.dtype(t) for t in (np.uint8, np.int8, np.uint16, np.int16, np.float16,
                                         np.float32))
_TIFF_TYPES = {np.dtype(np.uint8): "uint8", np.dtype(np.uint16): "uint16",
               np.dtype(np.int16): "int16", np.dtype(np.float16): "half",
               np.dtype(np.float32): "float", np.dtype(np.float64): "double"}
#: OpenEXR spectral channels (the decimal point written as a comma), and plain ``<nm>nm`` ones.
_CHANNEL = re.compile(r"^(S0|T)\.(\d+(?:,\d*)?)nm$")
_PLAIN_CHANNEL = re.compile(r"^(\d+(?:\.\d*)?)nm$")
#: A channel named as a spectral one (``S0.``, ``T.``), whether or not a wavelength follows.
_SPECTRAL_LIKE = re.compile(r"^(S0|T)\.")


# -- reading ---------------------------------------------------------------------------------


def _channel_wavelengths(path, names, texts):
    """The wavelengths (nm) channel ``names`` give as ``texts``; a channel whose number is no
    wavelength (400 digits read as infinity, 0, beyond :data:`WAVELENGTH_NM_RANGE`) refused,
    named with its file."""
    lo, hi = WAVELENGTH_NM_RANGE
    out = []
    for name, text in zip(names, texts, strict=True):
        try:
            w = float(text)
        except (ValueError, OverflowError):
            w = math.nan
        if not (math.isfinite(w) and lo <= w <= hi):
            raise ValueError(f"{path}: channel {shown(name)} names {shown(text)} nm, which is "
                             f"no wavelength (nm, {lo:g}-{hi:g}); rename the channel")
        out.append(w)
    return np.array(out, dtype=float)


def _description(attrs):
    """The JSON a TIFF's ImageDescription (or an EXR's ``snapcorr`` attribute) holds, or {}."""
    desc = attrs.get("ImageDescription") or attrs.get("snapcorr")
    if not (isinstance(desc, str) and desc.startswith("{")):
        return {}
    try:
        meta = parse_json(desc)
    except ValueError:
        return {}
    return meta if isinstance(meta, dict) else {}


def _check_tifffile_shape(path, meta, shape):
    """tifffile records the array it was given (``{"shape": [...]}``) and stores a 3-D one
    whose last axis is long as planes of its last two axes: ``(4, 5, 6)`` becomes 4 planes of
    5 x 6. Read as the file's own layout that is 5 x 6 pixels of 4 bands, where the writer may
    have meant 4 x 5 pixels of 6 bands. Which it meant cannot be told: refused."""
    given = meta.get("shape") if "written_by" not in meta else None
    if not (isinstance(given, list) and len(given) == 3):
        return
    given = tuple(int(v) for v in given)
    if given != tuple(shape) and given == (shape[2], shape[0], shape[1]):
        raise ValueError(
            f"{path}: tifffile was given an array of shape {given} and stored it as {given[0]} "
            f"planes of {given[1]} x {given[2]}; whether its bands are the first axis or the "
            "last cannot be told from the file. Write the cube (y, x, band) with "
            "tifffile.imwrite(path, cube, photometric='minisblack', planarconfig='contig'), or "
            "as .npy or .nc")


_NUMBERED = re.compile(r"^(.*?)(\d+)$")


def _exr_channel_order(path, names):
    """The bands' order of EXR channels not named by wavelength. OpenEXR keeps channels sorted
    by name (band1, band10, band11, band2, ...), not as written: channels named by one prefix
    and a number are put in the number's order, R, G, B (A) stay so (OpenImageIO's own order);
    any other naming is refused, as no order can be read from it."""
    if names == ["R", "G", "B", "A"][:len(names)]:  # OpenImageIO puts these first, in order
        return list(range(len(names)))
    parts = [_NUMBERED.match(n) for n in names]
    if all(parts) and len({m.group(1) for m in parts}) == 1:
        numbers = [int(m.group(2)) for m in parts]
        if len(set(numbers)) == len(numbers):
            return list(np.argsort(numbers, kind="stable"))
    shown = ", ".join(names[:6]) + (", ..." if len(names) > 6 else "")
    raise ValueError(f"{path}: OpenEXR keeps channels sorted by name, and these ({shown}) do "
                     "not say the bands' order; name them by wavelength (e.g. 'S0.550nm' or "
                     "'550nm') or by one prefix and the band's number (band1, band2, ...)")


def _read_oiio(path, fmt, drop_alpha, what="cube"):
    """The cube (or frame) of a TIFF or OpenEXR, in memory; ``drop_alpha`` leaves out an
    alpha channel."""
    import OpenImageIO as oiio

    inp = open_image(path)
    if inp is None:
        raise ValueError(f"{path}: cannot read it as {fmt}: "
                         f"{_one_line(oiio.geterror()) or 'OpenImageIO cannot open it'}")
    pages = []
    try:
        sub = 0
        while inp.seek_subimage(sub, 0):  # a multi-page TIFF: one band per page
            spec = inp.spec()
            _check_stored(path, fmt, spec, sub)
            pixels = _pixels(inp, spec, sub, path)
            names = list(spec.channelnames)
            if drop_alpha and len(names) > 1:
                keep = [i for i, n in enumerate(names) if n.upper() not in ("A", "ALPHA")]
                pixels, names = pixels[:, :, keep], [names[i] for i in keep]
            attrs = {a.name: a.value for a in spec.extra_attribs} if sub == 0 else {}
            pages.append((pixels, names, attrs))
            sub += 1
    finally:
        inp.close()
    if len(pages) > 1:
        return _oiio_pages(path, fmt, pages, what)
    data, names, attrs = pages[0]
    wl, keep, name = None, list(range(len(names))), None
    parsed = [_CHANNEL.match(n) for n in names]
    if any(parsed):
        keep = [i for i, m in enumerate(parsed) if m]
        odd = [n for n, m in zip(names, parsed, strict=True) if not m and _SPECTRAL_LIKE.match(n)]
        if odd:  # a band's channel whose name lost its wavelength (cut at 255 characters)
            raise ValueError(f"{path}: channel {shown(odd[0])} is named as a spectral channel "
                             f"but gives no wavelength (S0.<nm>nm or T.<nm>nm, the decimal "
                             f"point a comma); {len(keep)} others do: rename it")
        wl = _channel_wavelengths(path, [names[i] for i in keep],
                                  [parsed[i].group(2).replace(",", ".") for i in keep])
        name = "reflectance" if parsed[keep[0]].group(1) == "T" else "radiance"
        order = np.argsort(wl, kind="stable")  # EXR stores channels sorted by name
        keep, wl = [keep[i] for i in order], wl[order]
    meta = _description(attrs)
    if what == "cube":
        _check_tifffile_shape(path, meta, data.shape)
    written = meta.get("wavelength_nm")
    if isinstance(written, list) and len(written) == len(keep):
        written = check_wavelengths_nm("the description's wavelength_nm", written, where=path)
        if wl is None:
            wl = written
        elif np.array_equal(np.sort(written), wl):
            # EXR keeps channels sorted by name: put the bands back in the written order.
            order = np.argsort(np.argsort(written, kind="stable"), kind="stable")
            keep, wl = [keep[i] for i in order], wl[order]
    elif wl is None and names and all(_PLAIN_CHANNEL.match(n) for n in names):
        wl = _channel_wavelengths(path, names, [_PLAIN_CHANNEL.match(n).group(1) for n in names])
    elif wl is None and fmt == "exr" and len(keep) > 1:
        keep = [keep[i] for i in _exr_channel_order(path, [names[i] for i in keep])]
    data = data[..., keep]
    dtype = meta.get("dtype")
    if dtype is not None:
        data = _described_dtype(path, data, dtype)
    cube_attrs = meta.get("attrs", {})
    found = _File(path, fmt, data, wavelength=wl, fwhm=meta.get("fwhm_nm"),
                  name=meta.get("name") or name,
                  attrs={"source": str(path), **(cube_attrs if isinstance(cube_attrs, dict)
                                                 else {})})
    for key in POSITION_DIMS:
        if isinstance(meta.get(key), dict):
            found.positions[key] = meta[key]
    return found


#: TIFF photometric interpretations OpenImageIO would convert (to RGB, or inverted) rather
#: than give as stored; 1 (min-is-black, grey) and 2 (RGB, plain channels) are read as stored.
_CONVERTED_PHOTOMETRIC = {0: "min-is-white (inverted on reading)", 3: "a palette",
                          4: "a transparency mask", 5: "CMYK (separated)", 6: "YCbCr",
                          8: "CIE L*a*b*", 9: "ICC L*a*b*", 10: "ITU L*a*b*",
                          32844: "LogL", 32845: "LogLuv"}


def _check_stored(path, fmt, spec, sub):
    """Refuse a TIFF page whose samples OpenImageIO would rescale or convert: a bit depth
    other than its type's (12-bit counts come back bit-replicated to 16 bits, 1-bit ones as
    0/255) or a colour model other than grey or plain channels."""
    if fmt != "tiff":
        return
    where = f"page {sub + 1}" if sub else "the image"
    bits = spec.getattribute("oiio:BitsPerSample")
    if bits is not None and int(bits) != 8 * spec.format.size():
        raise ValueError(f"{path}: {where} stores {int(bits)}-bit samples, which would be "
                         f"rescaled to {spec.format} on reading, not read as stored; save the "
                         "values in 8, 16 or 32 bits per sample")
    photometric = spec.getattribute("tiff:PhotometricInterpretation")
    if photometric is not None and int(photometric) not in (1, 2):
        what = _CONVERTED_PHOTOMETRIC.get(int(photometric), f"photometric {int(photometric)}")
        raise ValueError(f"{path}: {where} is stored as {what}, which would be converted on "
                         "reading, not read as stored; save the values as grey "
                         "(min-is-black) or plain channels")


def _pixels(inp, spec, sub, path):
    """A page's pixels ``(height, width, channels)`` as stored: channels of mixed types (an
    OpenEXR's uint beside float ones) each read in its own type, since one common type
    would give the integers normalised to [0, 1]."""
    formats = list(spec.channelformats)
    if formats and len({str(f) for f in formats}) > 1:
        chans = [inp.read_image(sub, 0, c, c + 1, formats[c]) for c in range(spec.nchannels)]
        if any(c is None for c in chans):
            raise ValueError(f"{path}: cannot read page {sub + 1}: "
                             f"{_one_line(inp.geterror()) or 'no pixels'}")
        chans = [np.asarray(c).reshape(spec.height, spec.width) for c in chans]
        common = np.result_type(*chans)
        if common.kind == "f" and any(c.dtype.kind in "iu" and c.dtype.itemsize >= 4
                                      for c in chans):
            common = np.dtype(np.float64)  # 32-bit integers held exactly
        return np.stack([c.astype(common) for c in chans], axis=2)
    pixels = inp.read_image(sub, 0, 0, spec.nchannels, "unknown")
    if pixels is None:
        raise ValueError(f"{path}: cannot read page {sub + 1}: "
                         f"{_one_line(inp.geterror()) or 'no pixels'}")
    return np.asarray(pixels).reshape(spec.height, spec.width, spec.nchannels)


def _described_dtype(path, data, dtype):
    """``data`` in the dtype its description names: the stored one, or one its values convert
    to exactly (snapcorr writes integers into OpenEXR's float channels; OpenImageIO gives a
    TIFF's half floats as float32). Anything else (a file re-saved in another type under the
    old description) is refused."""
    try:
        dtype = np.dtype(dtype)
    except TypeError:
        raise ValueError(f"{path}: the description names an unknown dtype {shown(dtype)}") from None
    if dtype == data.dtype:
        return data
    if dtype in _EXR_EXACT:
        with np.errstate(invalid="ignore", over="ignore"):
            cast = data.astype(dtype)
        if np.array_equal(cast.astype(data.dtype), data, equal_nan=dtype.kind == "f"):
            return cast
    raise ValueError(f"{path}: the description says {dtype} but the file stores {data.dtype} "
                     "values that do not convert exactly (re-saved by another program "
                     "with the old description?); remove or correct its 'dtype'")


def _oiio_pages(path, fmt, pages, what):
    """A multi-page file: every page one channel (one band), all the same size and type."""
    first = pages[0][0]
    for i, (pixels, _, _) in enumerate(pages, start=1):
        if pixels.shape[2] != 1:
            raise ValueError(f"{path}: page {i} has {pixels.shape[2]} channels; a multi-page "
                             f"{fmt.upper()} holds one band per page, each of one channel")
        if pixels.shape[:2] != first.shape[:2] or pixels.dtype != first.dtype:
            raise ValueError(f"{path}: page {i} is {pixels.shape[1]} x {pixels.shape[0]} "
                             f"{pixels.dtype} but page 1 is {first.shape[1]} x {first.shape[0]} "
                             f"{first.dtype}; every page (band) must match")
    data = np.concatenate([p[0] for p in pages], axis=2)
    if what == "cube":  # a stack of frames or flats: pages are pages
        _check_tifffile_shape(path, _description(pages[0][2]), data.shape)
    names = [p[1][0] for p in pages]
    wl = None
    if all(_PLAIN_CHANNEL.match(n) for n in names):
        wl = _channel_wavelengths(path, names, [_PLAIN_CHANNEL.match(n).group(1) for n in names])
    return _File(path, fmt, data, wavelength=wl, attrs={"source": str(path)})


# -- writing ---------------------------------------------------------------------------------


def _channel_name(prefix, wavelength):
    return f"{prefix}.{float(wavelength)!r}nm".replace(".", ",").replace(",", ".", 1)


def _write_oiio(cube, path, meta, *, interleave):
    import OpenImageIO as oiio

    exr = path.suffix.lower() == ".exr"
    data = np.ascontiguousarray(cube.values)
    if exr:
        prefix = "T" if cube.name in _REFLECTIVE else "S0"
        names = [_channel_name(prefix, w) for w in cube.wavelength.values]
        store = data.astype(np.float16 if data.dtype == np.float16 else np.float32)
        typedesc = "half" if data.dtype == np.float16 else "float"
    else:
        names = [f"{float(w)!r}nm" for w in cube.wavelength.values]
        store, typedesc = data, _TIFF_TYPES[data.dtype]
    ny, nx, nb = store.shape
    spec = oiio.ImageSpec(nx, ny, nb, typedesc)
    spec.channelnames = tuple(names)
    spec.alpha_channel = -1
    spec.attribute("ImageDescription", json.dumps(meta))
    spec.attribute("compression", "zip")
    if exr:
        spec.attribute("spectralLayoutVersion", "1.0")
        if prefix == "S0":
            spec.attribute("emissiveUnits", "W.m^-2.sr^-1")
    else:
        spec.attribute("tiff:PlanarConfiguration", "contig")

    def write(tmp):
        out = oiio.ImageOutput.create(str(path))
        if out is None or not out.open(str(tmp), spec):
            raise ValueError(f"cannot write {path}: {_one_line(oiio.geterror())}")
        try:
            if not out.write_image(store):
                raise ValueError(f"cannot write {path}: {_one_line(out.geterror())}")
        finally:
            out.close()

    atomic_write(path, write)


def _check_exr_writable(cube, path, interleave):
    if cube.dtype not in _EXR_EXACT:
        raise ValueError(
            f"OpenEXR stores 16- and 32-bit floats, so a {cube.dtype} cube would not come "
            "back unchanged; convert it (cube.astype('float32')) or write .nc, .zarr or .tif"
        )


def _check_tiff_writable(cube, path, interleave):
    if cube.dtype not in _TIFF_TYPES:
        raise ValueError(f"snapcorr writes TIFF cubes as 8/16-bit integers or 16/32/64-bit "
                         f"floats, not {cube.dtype}; convert it or write .nc or .zarr")


def _read_tiff(path, data_file, chunks, what, drop_alpha):
    return _read_oiio(path, "tiff", drop_alpha, what)


def _read_exr(path, data_file, chunks, what, drop_alpha):
    return _read_oiio(path, "exr", drop_alpha, what)


#: TIFF through OpenImageIO (its mark: ``written_by`` in the JSON image description).
TIFF = FileFormat("tiff", (".tif", ".tiff"), _read_tiff, _write_oiio, marked_as=("tiff",),
                  check_writable=_check_tiff_writable, native_byte_order=True)
#: OpenEXR through OpenImageIO (its mark: as TIFF's).
EXR = FileFormat("exr", (".exr",), _read_exr, _write_oiio, marked_as=("exr",),
                 check_writable=_check_exr_writable, native_byte_order=True)
