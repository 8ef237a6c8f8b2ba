"""Compatibility re-exports: a stream of raw mosaic frames through the pipeline is
:func:`snapcorr.pipeline.process_stream`."""

from .pipeline import process_stream

_MOVED_TO = "snapcorr.pipeline"

__all__ = ["process_stream"]
