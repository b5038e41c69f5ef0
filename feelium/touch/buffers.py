"""Working-size arrays the touch pipeline reuses frame after frame instead of allocating them anew.

Why: the daemon fixes glibc's mmap threshold at 128 KB (``[daemon] malloc_mmap_threshold_kb``), so every
float32 working image (196 KB for the 320x240 working frame's ROI) allocated per frame was an mmap whose
pages faulted in again on every frame, and the smaller bool masks grew the heap that glibc then trimmed back
to the kernel; at 30 fps that churn was about half of the pipeline's CPU time (docs/performance.md). A
stage writes into its buffer with ``out=``/``dst=`` and never lets it outlive the frame: whatever is kept
across frames (the reference, the shadow mask, the learned response) stays its own array.
"""

from __future__ import annotations

import numpy as np


class Scratch:
    """Named buffers: ``get`` returns the same array for the same name, shape and dtype (contents undefined)."""

    def __init__(self) -> None:
        self._arrays: dict[str, np.ndarray] = {}

    def get(self, name: str, shape: tuple[int, ...], dtype: type | np.dtype) -> np.ndarray:
        """The buffer called ``name``; a new one when the shape or dtype asked for changed (a new ROI)."""
        array = self._arrays.get(name)
        if array is None or array.shape != shape or array.dtype != dtype:
            array = self._arrays[name] = np.empty(shape, dtype)
        return array

    def like(self, name: str, template: np.ndarray, dtype: type | np.dtype | None = None) -> np.ndarray:
        """The buffer called ``name`` with ``template``'s shape (and dtype unless given).

        :meth:`get`'s lookup written out: the pipeline asks for ~40 buffers a frame, and on the Pi a Python call
        is worth saving there (issue 16)."""
        wanted = template.dtype if dtype is None else dtype  # a dtype compares equal to its type (``bool``)
        array = self._arrays.get(name)
        if array is None or array.shape != template.shape or array.dtype != wanted:
            array = self._arrays[name] = np.empty(template.shape, wanted)
        return array
