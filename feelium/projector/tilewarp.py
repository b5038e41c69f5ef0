"""The canvas-to-projector warp, redone only where the canvas changed since the previous frame.

The projector runs at 30 fps, but between two frames little of the skin canvas
changes: the wearer's face video updates at ~12 fps and most frames differ
only where a touch answer animates. The warp (a remap of ~0.5 M projector
pixels) is most of a frame's cost, so each frame compares the canvas with
the previous one in source tiles and re-warps only the destination tiles
that read a changed source tile; the rest of the frame is the previous one.

Which source pixels a destination tile reads is known in advance: the
fixed-point map (``CV_16SC2``) holds each pixel's integer source position,
and bilinear interpolation reads it and its right, lower and diagonal
neighbours. So the result is the full warp's, pixel for pixel.

With a ``scale`` below one the maps are for a coarser grid than the projector's (the resolution the skin
resolves, chosen by :func:`feelium.projector.optics.warp_scale`): the canvas is remapped onto that grid, which
is kept whole, and the changed part of it is scaled up to projector pixels with a bilinear resize, several
times cheaper per pixel than a remap. The full and the tiled warp then agree to within a grey level (the
resize's fixed-point weights of a piece and of the whole may round apart), not pixel for pixel.

Frames handed out are never written while anyone holds them: the display,
the HTTP preview and the back-light predictor can keep one as long as they
like. A frame buffer is reused only once nothing but the pool refers to it.
"""

from __future__ import annotations

import sys
import threading
from collections.abc import Iterator
from dataclasses import dataclass

import cv2
import numpy as np

DEST_TILE = (32, 16)  # (w, h) projector pixels re-warped together: a run of these is one remap call
SOURCE_TILE = 16  # canvas pixels per side of the squares compared between frames
FULL_ABOVE = 0.5  # above this fraction of dirty destination tiles one full remap is cheaper than the runs
SCALE_MARGIN = 2  # scale steps around a re-warped piece scaled up with it (bilinear reads one coarse pixel on)
POOL_SIZE = 3  # frame buffers kept for reuse: the newest (shown, previewed), one being drawn, one held late


class TileWarp:
    """Warps canvases through fixed-point maps covering ``box`` of the frame; keeps the last canvas and frame.

    One caller at a time (a lock serialises callers from several threads).
    """

    def __init__(
        self,
        map1: np.ndarray,
        map2: np.ndarray,
        box: tuple[int, int, int, int],
        canvas_size: tuple[int, int],
        frame_size: tuple[int, int],
        border: tuple[int, ...],
        scale: tuple[int, int] = (1, 1),
    ) -> None:
        """``map1``/``map2``: ``cv2.convertMaps(..., CV_16SC2)`` output for the ``box`` (x0, y0, x1, y1) of a
        ``frame_size`` (w, h) BGR frame whose pixels outside the box are ``border``; ``canvas_size`` (w, h) of the
        canvases to warp. No blank frame is kept to copy from: a new frame is filled with ``border`` (a kept
        template was 2.7 MB resident for the daemon's whole life).

        ``scale`` (num, den): the maps are for a grid num/den of the box's size in each axis (the box's sides
        are den/num times the maps'), whose every point (j, i) is the box pixel ((j + 0.5) den/num - 0.5, ...);
        num must divide the destination tile's sides so that tiles fall on whole box pixels."""
        num, den = scale
        h, w = map1.shape[:2]
        x0, y0, x1, y1 = box
        if (x1 - x0) * num != w * den or (y1 - y0) * num != h * den or DEST_TILE[0] % num or DEST_TILE[1] % num:
            raise ValueError(f"a {w}x{h} map at scale {num}/{den} does not cover the {x1 - x0}x{y1 - y0} box in whole tiles")
        self._scale = scale
        # The coarse grid's picture, kept whole between calls: what changed is re-warped into it, then scaled up.
        self._coarse = np.empty((h, w, len(border)), np.uint8) if num != den else None
        self._map1, self._map2, self._box = map1, map2, box
        self._frame_shape, self._border = (frame_size[1], frame_size[0], len(border)), border
        cw, ch = canvas_size
        self._grid = (-(-ch // SOURCE_TILE), -(-cw // SOURCE_TILE))
        ny, nx = self._grid
        # The canvas difference is reduced in a buffer padded to whole source tiles (the padding stays 0).
        self._diff = np.zeros((ny * SOURCE_TILE, nx * SOURCE_TILE, 3), np.uint8)
        self._canvas_size = canvas_size
        self._corners, self._reads = _source_tile_corners(map1, canvas_size, self._grid)
        self._prev_canvas: np.ndarray | None = None
        self._frame: _Buffer | None = None
        self._pool: list[_Buffer] = []
        self._lock = threading.Lock()
        self.last_dirty_fraction = 1.0  # of the destination tiles re-warped by the newest call, for the benchmark
        self.allocated = 0  # frame buffers allocated (the rest of the frames reused one nobody held any more)

    def full(self, canvas: np.ndarray) -> np.ndarray:
        """The straightforward warp: every covered pixel remapped into a new frame."""
        frame = self._blank()
        self._remap_box(canvas, frame)
        return frame

    def warp(self, canvas: np.ndarray) -> np.ndarray:
        """The frame of ``canvas``, equal to :meth:`full`'s, re-warping only what changed since the last call."""
        cw, ch = self._canvas_size
        if canvas.shape != (ch, cw, 3) or canvas.dtype != np.uint8:
            raise ValueError(f"canvas must be {cw}x{ch} BGR uint8, got {canvas.shape} {canvas.dtype}")
        with self._lock:
            return self._warp(canvas)

    def _warp(self, canvas: np.ndarray) -> np.ndarray:
        prev, current = self._prev_canvas, self._frame
        if prev is None or current is None:
            self._prev_canvas = canvas.copy()  # the caller may reuse its array: keep our own
            dirty = self._reads
        else:
            dirty = self._dirty_tiles(self._changed_source_tiles(canvas, prev))
            np.copyto(prev, canvas)
        self.last_dirty_fraction = float(dirty.mean())
        if current is not None and not dirty.any():
            return current.array  # unchanged: the newest frame again (a pool never writes its newest)
        # Scaled up, a re-warped tile's edge blends into its neighbours' edges: they change too (a ring of
        # one coarse pixel, redone with the tile), and other buffers must catch up on them.
        touched = dirty if self._coarse is None else _grow(dirty)
        target = self._free_buffer()
        if current is None or dirty.mean() > FULL_ABOVE:
            self._remap_box(canvas, target.array)
        else:
            # The buffer holds an older frame: bring the tiles that changed since then up to date from the
            # newest frame (a copy), then re-warp what changed now.
            behind = target.stale & ~dirty  # copied before the rings around the dirty tiles are redone
            into, newest = self._in_box(target.array), self._in_box(current.array)
            num, den = self._scale
            if behind.mean() > FULL_ABOVE:
                np.copyto(into, newest)
            else:
                for ys, xs in self._runs(behind, den, num):
                    into[ys, xs] = newest[ys, xs]
            coarse = into if self._coarse is None else self._coarse
            runs = list(self._runs(dirty))
            for ys, xs in runs:
                cv2.remap(canvas, self._map1[ys, xs], self._map2[ys, xs], cv2.INTER_LINEAR, dst=coarse[ys, xs],
                          borderMode=cv2.BORDER_CONSTANT, borderValue=self._border)
            if self._coarse is not None:
                for ys, xs in runs:
                    self._scale_up_part(ys, xs, into)
        for buffer in self._pool:
            buffer.stale |= touched
        target.stale[...] = False
        self._frame = target
        return target.array

    def _free_buffer(self) -> _Buffer:
        """A pooled frame buffer nobody else holds (the newest frame excluded), else a new one.

        Frames handed out are read by the display, the HTTP preview and the back-light predictor for as
        long as they keep a reference; a buffer only the pool references can be written. Reusing them
        spares a 2.7 MB allocation per frame, which the daemon's malloc settings make an mmap whose
        page faults cost about as much as the warp itself.
        """
        for buffer in self._pool:
            if buffer is not self._frame and sys.getrefcount(buffer.array) <= 2:  # the pool's and the argument's
                return buffer
        fresh = _Buffer(self._blank(), self._reads.copy() if self._coarse is None else _grow(self._reads))
        self.allocated += 1
        if len(self._pool) < POOL_SIZE:
            self._pool.append(fresh)
        else:  # every pooled frame is still held: hand the oldest over to its holders
            held = next(b for b in self._pool if b is not self._frame)
            self._pool[self._pool.index(held)] = fresh
        return fresh

    def _blank(self) -> np.ndarray:
        """A new frame of the border colour (the box is written over by the caller)."""
        frame = np.empty(self._frame_shape, np.uint8)
        frame[...] = self._border
        return frame

    def _in_box(self, frame: np.ndarray) -> np.ndarray:
        x0, y0, x1, y1 = self._box
        return frame[y0:y1, x0:x1]

    def _remap_box(self, canvas: np.ndarray, frame: np.ndarray) -> None:
        into = self._in_box(frame)
        coarse = into if self._coarse is None else self._coarse
        cv2.remap(canvas, self._map1, self._map2, cv2.INTER_LINEAR, dst=coarse,
                  borderMode=cv2.BORDER_CONSTANT, borderValue=self._border)
        if self._coarse is not None:
            cv2.resize(self._coarse, (into.shape[1], into.shape[0]), dst=into, interpolation=cv2.INTER_LINEAR)

    def _scale_up_part(self, ys: slice, xs: slice, into: np.ndarray) -> None:
        """Scale the coarse grid's rows ``ys``, columns ``xs`` and a ring of one scale step (``num`` coarse
        pixels) around them up into their box pixels of ``into``: the ring's box pixels blend the piece's.

        Bilinear weights near a piece's edge would read past it (the resize replicates the edge), so a
        margin of ``SCALE_MARGIN`` scale steps (whole steps, so it starts on a box pixel) is scaled with it
        and cut off, except at the grid's own edges, where the whole resize replicates too.
        """
        coarse = self._coarse
        assert coarse is not None, "scaled up only with a coarse grid"
        num, den = self._scale
        h, w = coarse.shape[:2]
        margin = SCALE_MARGIN * num
        a, b = max(ys.start - margin, 0), min(ys.stop + margin, h)
        c, d = max(xs.start - margin, 0), min(xs.stop + margin, w)
        part = cv2.resize(coarse[a:b, c:d], ((d - c) * den // num, (b - a) * den // num), interpolation=cv2.INTER_LINEAR)
        r0, r1 = max(ys.start - num, 0) * den // num, min(ys.stop + num, h) * den // num
        c0, c1 = max(xs.start - num, 0) * den // num, min(xs.stop + num, w) * den // num
        into[r0:r1, c0:c1] = part[r0 - a * den // num : r1 - a * den // num, c0 - c * den // num : c1 - c * den // num]

    def _changed_source_tiles(self, canvas: np.ndarray, prev: np.ndarray) -> np.ndarray:
        """(ny, nx) bool: source tiles with any channel of any pixel different from ``prev``."""
        ch, cw = canvas.shape[:2]
        ny, nx = self._grid
        cv2.absdiff(canvas, prev, dst=self._diff[:ch, :cw])
        # Reduce over each band's rows first (long contiguous rows: fast), then within each tile's columns.
        bands = self._diff.reshape(ny, SOURCE_TILE, -1).max(axis=1)
        return bands.reshape(ny, nx, SOURCE_TILE * 3).max(axis=2) > 0

    def _dirty_tiles(self, changed: np.ndarray) -> np.ndarray:
        """(rows, cols) bool over destination tiles: those reading at least one changed source tile."""
        ny, nx = self._grid
        table = np.zeros((ny + 1, nx + 1), np.int32)
        np.cumsum(np.cumsum(changed, axis=0, dtype=np.int32), axis=1, out=table[1:, 1:])
        flat = table.ravel()
        i00, i01, i10, i11 = self._corners
        return (flat[i11] - flat[i01] - flat[i10] + flat[i00] > 0).reshape(self._reads.shape)

    def _runs(self, tiles: np.ndarray, den: int = 1, num: int = 1) -> Iterator[tuple[slice, slice]]:
        """Slices (rows, columns) of the maps' grid, or with ``den``/``num`` the scale, of the box, for each
        rectangle of marked destination tiles (:func:`tile_rectangles`): one remap or copy per rectangle."""
        tw, th = DEST_TILE[0] * den // num, DEST_TILE[1] * den // num
        for r0, r1, c0, c1 in tile_rectangles(tiles):
            yield slice(r0 * th, r1 * th), slice(c0 * tw, c1 * tw)  # slicing clips the last tiles to the box


def tile_rectangles(tiles: np.ndarray) -> list[tuple[int, int, int, int]]:
    """Disjoint rectangles ``(row0, row1, col0, col1)`` (ends exclusive) covering exactly the marked cells.

    Each row's horizontal runs come from array operations over the whole grid at once (a numpy call per
    row cost more than the remaps it fed), and a run spanning the same columns as one in the row above
    extends that rectangle downwards: an animated answer's blob is a few tall rectangles, so a few remap
    calls (each costs ~10 us of set-up whatever its size) instead of one per row.
    """
    padded = np.zeros((tiles.shape[0], tiles.shape[1] + 2), np.int8)  # np.pad cost ~50 us a call, 3x this
    padded[:, 1:-1] = tiles
    edges = np.diff(padded, axis=1)
    start_rows, start_cols = np.nonzero(edges > 0)
    end_cols = np.nonzero(edges < 0)[1]  # row-major like the starts: the i-th end closes the i-th start
    done: list[tuple[int, int, int, int]] = []
    growing: dict[tuple[int, int], tuple[int, int]] = {}  # (col0, col1) -> (first row, last row)
    for row, c0, c1 in zip(start_rows.tolist(), start_cols.tolist(), end_cols.tolist()):
        span = growing.get((c0, c1))
        if span is not None and span[1] == row - 1:
            growing[(c0, c1)] = (span[0], row)
            continue
        if span is not None:
            done.append((span[0], span[1] + 1, c0, c1))
        growing[(c0, c1)] = (row, row)
    done.extend((r0, r1 + 1, c0, c1) for (c0, c1), (r0, r1) in growing.items())
    return done


def _grow(tiles: np.ndarray) -> np.ndarray:
    """The marked tiles and their eight neighbours."""
    rows, cols = tiles.shape
    padded = np.zeros((rows + 2, cols + 2), bool)
    padded[1:-1, 1:-1] = tiles
    grown = np.zeros_like(tiles)
    for dy in range(3):
        for dx in range(3):
            grown |= padded[dy : dy + rows, dx : dx + cols]
    return grown


@dataclass(eq=False)
class _Buffer:
    """A pooled frame and which destination tiles of it are older than the newest frame."""

    array: np.ndarray
    stale: np.ndarray


def _source_tile_corners(
    map1: np.ndarray, canvas_size: tuple[int, int], grid: tuple[int, int]
) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray], np.ndarray]:
    """For each destination tile, the four flat indices into a (ny+1, nx+1) summed-area table of changed
    source tiles that count the changed tiles inside the box of source tiles the destination tile reads;
    and which destination tiles read the canvas at all (rows, cols).

    A destination pixel whose integer source position is (x, y) reads x..x+1, y..y+1 (bilinear); taps
    outside the canvas read the border colour, which never changes. A tile reading no canvas pixel gets
    an empty box (all four indices 0), so it is never dirty.
    """
    cw, ch = canvas_size
    ny, nx = grid
    tw, th = DEST_TILE
    h, w = map1.shape[:2]
    rows, cols = -(-h // th), -(-w // tw)
    x = map1[:, :, 0].astype(np.int32)
    y = map1[:, :, 1].astype(np.int32)
    reads = (x + 1 >= 0) & (x < cw) & (y + 1 >= 0) & (y < ch)
    lo_x, hi_x = np.clip(x, 0, cw - 1), np.clip(x + 1, 0, cw - 1)
    lo_y, hi_y = np.clip(y, 0, ch - 1), np.clip(y + 1, 0, ch - 1)

    def per_tile(values: np.ndarray, reduce: np.ufunc, empty: int) -> np.ndarray:
        padded = np.full((rows * th, cols * tw), empty, np.int32)
        padded[:h, :w] = np.where(reads, values, empty)
        return reduce.reduce(reduce.reduce(padded.reshape(rows, th, cols, tw), axis=3), axis=1)

    big = np.iinfo(np.int32).max
    x0, x1 = per_tile(lo_x, np.minimum, big), per_tile(hi_x, np.maximum, -1)
    y0, y1 = per_tile(lo_y, np.minimum, big), per_tile(hi_y, np.maximum, -1)
    empty = x1 < 0
    sx0, sx1, sy0, sy1 = x0 // SOURCE_TILE, x1 // SOURCE_TILE, y0 // SOURCE_TILE, y1 // SOURCE_TILE
    stride = nx + 1
    # Summed-area table T (ny+1, nx+1): tiles in rows sy0..sy1, columns sx0..sx1 count
    # T[sy1+1, sx1+1] - T[sy0, sx1+1] - T[sy1+1, sx0] + T[sy0, sx0]; an empty box gives 0 - 0 - 0 + 0.
    i11 = np.where(empty, 0, (sy1 + 1) * stride + sx1 + 1).ravel()
    i01 = np.where(empty, 0, sy0 * stride + sx1 + 1).ravel()
    i10 = np.where(empty, 0, (sy1 + 1) * stride + sx0).ravel()
    i00 = np.where(empty, 0, sy0 * stride + sx0).ravel()
    return (i00, i01, i10, i11), ~empty
