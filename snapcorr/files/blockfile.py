"""Raw binary cubes (``.npy``, ENVI) read lazily in blocks of rows, with plain file reads.

A memory map of the whole file would do the same work, but every page it touches stays in the
process's resident memory and the map takes the file's size of address space, so a cube
larger than memory (or than an address-space limit) could not stream. Here each block is read
with ``readinto`` at its offset and is the only part in memory; dask schedules the blocks
(:func:`dask.array.from_array` over :class:`RowBlockFile`, as xarray's backends do).
"""

from __future__ import annotations

import numpy as np

__all__ = ["INTERLEAVES", "RowBlockFile", "lazy_file_array"]

#: Layouts of the bytes on disk, as ENVI names them: the file's axes in order.
INTERLEAVES = {"bip": ("y", "x", "band"), "bil": ("y", "band", "x"), "bsq": ("band", "y", "x")}


class RowBlockFile:
    """An array-like ``(y, x, band)`` view of a raw file; indexing reads only what is asked.

    Parameters
    ----------
    path : str or Path
    dtype : numpy dtype
        As stored, with its byte order; blocks come back in native byte order.
    shape : (ny, nx, nb)
    offset : int
        Bytes before the first value (a header).
    interleave : {"bip", "bil", "bsq"}
        ``.npy`` (C order, ``(y, x, band)``) is ``"bip"``.
    """

    def __init__(self, path, dtype, shape, offset=0, interleave="bip"):
        if interleave not in INTERLEAVES:
            raise ValueError(f"interleave must be one of {sorted(INTERLEAVES)}, got "
                             f"{interleave!r}")
        self.path, self.file_dtype = str(path), np.dtype(dtype)
        self.dtype = self.file_dtype.newbyteorder("=")
        self.shape, self.offset, self.interleave = tuple(int(n) for n in shape), offset, interleave
        self.ndim = 3

    def _read(self, fh, start, count):
        out = np.empty(count, self.file_dtype)
        fh.seek(self.offset + start * self.file_dtype.itemsize)
        got = fh.readinto(memoryview(out).cast("B"))
        if got != out.nbytes:
            raise OSError(f"{self.path}: the file ends early (read {got} of {out.nbytes} bytes "
                          f"at offset {self.offset + start * self.file_dtype.itemsize})")
        return out

    def rows(self, r0, r1):
        """Rows ``r0:r1`` as a native-order ``(rows, nx, nb)`` array."""
        ny, nx, nb = self.shape
        n = r1 - r0
        with open(self.path, "rb") as fh:
            if self.interleave == "bip":
                block = self._read(fh, r0 * nx * nb, n * nx * nb).reshape(n, nx, nb)
            elif self.interleave == "bil":
                block = self._read(fh, r0 * nb * nx, n * nb * nx).reshape(n, nb, nx)
                block = block.transpose(0, 2, 1)
            else:  # bsq: one read per band
                block = np.empty((n, nx, nb), self.file_dtype)
                for b in range(nb):
                    block[:, :, b] = self._read(fh, (b * ny + r0) * nx, n * nx).reshape(n, nx)
        return np.ascontiguousarray(block, dtype=self.dtype)

    def __getitem__(self, key):
        key = key if isinstance(key, tuple) else (key,)
        key = key + (slice(None),) * (3 - len(key))
        rows = np.arange(self.shape[0])[key[0]]  # a slice, an index or an index array
        if rows.ndim == 0:
            return self.rows(int(rows), int(rows) + 1)[0][key[1:]]
        lo = int(rows.min()) if rows.size else 0
        hi = int(rows.max()) + 1 if rows.size else 0
        block = self.rows(lo, hi)
        if not (rows.size == hi - lo and np.all(np.diff(rows) == 1)):
            block = block[rows - lo]
        return block[(slice(None), *key[1:])]


def lazy_file_array(path, dtype, shape, *, offset=0, interleave="bip", rows_per_block):
    """A dask array over a raw file, one task per block of ``rows_per_block`` rows.

    Parameters
    ----------
    path : str or Path
    dtype : numpy dtype
        As stored, with its byte order; the array is in native byte order.
    shape : (ny, nx, nb)
        The cube's shape, whatever the layout on disk.
    offset : int
        Bytes before the first value (a header).
    interleave : {"bip", "bil", "bsq"}
        Layout on disk (:data:`INTERLEAVES`).
    rows_per_block : int
        Rows of ``y`` per chunk; each chunk spans all ``x`` and bands.

    Returns
    -------
    dask.array.Array
        Shape ``(ny, nx, nb)``.
    """
    import dask.array as da

    source = RowBlockFile(path, dtype, shape, offset, interleave)
    return da.from_array(source, chunks=(int(rows_per_block), -1, -1), asarray=True,
                         fancy=False, name=f"read-{abs(hash((str(path), offset, shape))):x}")
