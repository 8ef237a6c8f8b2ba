"""Compatibility re-exports: this module moved to :mod:`snapcorr.files.safety`, with
:mod:`~snapcorr.files.reading`, :mod:`~snapcorr.files.marks`, :mod:`~snapcorr.files.outputs`,
:mod:`~snapcorr.files.png` and :mod:`~snapcorr.files.toml` beside it."""

# ruff: noqa: F401

from snapcorr.files.marks import _MARK as _MARK
from snapcorr.files.marks import _PNG_LIMIT as _PNG_LIMIT
from snapcorr.files.marks import _PNG_SIGNATURE as _PNG_SIGNATURE
from snapcorr.files.marks import _TEXT_LIMIT as _TEXT_LIMIT
from snapcorr.files.marks import _TIED_RE as _TIED_RE
from snapcorr.files.marks import _check_content as _check_content
from snapcorr.files.marks import _chunk as _chunk
from snapcorr.files.marks import _png_chunks as _png_chunks
from snapcorr.files.marks import _png_software as _png_software
from snapcorr.files.marks import _png_text as _png_text
from snapcorr.files.marks import _png_token as _png_token
from snapcorr.files.marks import _stamp_png as _stamp_png
from snapcorr.files.marks import _token as _token
from snapcorr.files.marks import mark_matches as mark_matches
from snapcorr.files.marks import tied_mark as tied_mark
from snapcorr.files.marks import toml_mark as _toml_mark
from snapcorr.files.marks import untie_mark as untie_mark
from snapcorr.files.marks import written_by_snapcorr as written_by_snapcorr
from snapcorr.files.outputs import check_replaceable as check_replaceable
from snapcorr.files.png import save_png as save_png
from snapcorr.files.reading import NotRegularFileError as NotRegularFileError
from snapcorr.files.reading import _check_store_entries as _check_store_entries
from snapcorr.files.reading import _found as _found
from snapcorr.files.reading import check_input as check_input
from snapcorr.files.reading import file_kind as file_kind
from snapcorr.files.reading import read_regular as read_regular
from snapcorr.files.safety import _CHECKED as _CHECKED
from snapcorr.files.safety import _LOCK as _LOCK
from snapcorr.files.safety import _REMOVED as _REMOVED
from snapcorr.files.safety import _SCOPE_IDS as _SCOPE_IDS
from snapcorr.files.safety import _SCOPES as _SCOPES
from snapcorr.files.safety import _TEMPORARY as _TEMPORARY
from snapcorr.files.safety import _WRITTEN as _WRITTEN
from snapcorr.files.safety import _WRITTEN_KEEP as _WRITTEN_KEEP
from snapcorr.files.safety import OutputChangedError as OutputChangedError
from snapcorr.files.safety import _changed as _changed
from snapcorr.files.safety import _changed_since_check as _changed_since_check
from snapcorr.files.safety import _check_kind as _check_kind
from snapcorr.files.safety import _expected as _expected
from snapcorr.files.safety import _identity as _identity
from snapcorr.files.safety import _interrupt as _interrupt
from snapcorr.files.safety import _key as _key
from snapcorr.files.safety import _make_temporary as _make_temporary
from snapcorr.files.safety import _move_in_new as _move_in_new
from snapcorr.files.safety import _note_written as _note_written
from snapcorr.files.safety import _register as _register
from snapcorr.files.safety import _remove_left_over as _remove_left_over
from snapcorr.files.safety import _replace as _replace
from snapcorr.files.safety import _resolved as _resolved
from snapcorr.files.safety import _stamp as _stamp
from snapcorr.files.safety import _state as _state
from snapcorr.files.safety import _target_key as _target_key
from snapcorr.files.safety import _umask as _umask
from snapcorr.files.safety import _unregister as _unregister
from snapcorr.files.safety import _usual_permissions as _usual_permissions
from snapcorr.files.safety import _write_and_move as _write_and_move
from snapcorr.files.safety import atomic_write as atomic_write
from snapcorr.files.safety import atomic_write_dir as atomic_write_dir
from snapcorr.files.safety import atomic_write_files as atomic_write_files
from snapcorr.files.safety import checked_outputs as checked_outputs
from snapcorr.files.safety import cleanup_on_signals as cleanup_on_signals
from snapcorr.files.safety import last_written as last_written
from snapcorr.files.safety import note_checked as note_checked
from snapcorr.files.safety import refuse_inputs as refuse_inputs
from snapcorr.files.safety import remove_path as remove_path
from snapcorr.files.safety import temporary_paths as temporary_paths
from snapcorr.files.toml import read_toml as read_toml
from snapcorr.files.toml import write_toml as write_toml

#: Names whose files carry a mark tied to the name they are written as.
_TIED = (".nc", ".zarr", ".hdr", ".npy.json")

_MOVED_TO = "snapcorr.files.safety"

__all__ = [
    "atomic_write",
    "atomic_write_dir",
    "atomic_write_files",
    "check_input",
    "check_replaceable",
    "checked_outputs",
    "cleanup_on_signals",
    "file_kind",
    "last_written",
    "note_checked",
    "read_regular",
    "read_toml",
    "refuse_inputs",
    "remove_path",
    "save_png",
    "temporary_paths",
    "write_toml",
]
