"""A small labelled recording made in the test: an unevenly lit membrane and one dark disc pressed for 0.5 s.

Written with the project's own RecordingWriter, so replay, the daemon and the
touch pipeline are exercised on the real format without committing video.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from feelium.recording import Contact, Labels, RecordingWriter

WIDTH, HEIGHT, FPS = 320, 240, 15.0
ROI = (32, 24, 256, 192)
PRESS_XY = (170.0, 110.0)
PRESS_ON, PRESS_OFF = 1.6, 2.1


def frame(t: float, rng: np.random.Generator) -> np.ndarray:
    """Back-light falling 3:1 from centre to corners, a 10 px dark disc while pressed, sensor noise."""
    ys, xs = np.mgrid[0:HEIGHT, 0:WIDTH].astype(np.float32)
    r2 = ((xs - WIDTH / 2) / (WIDTH / 2)) ** 2 + ((ys - HEIGHT / 2) / (HEIGHT / 2)) ** 2
    img = 210.0 / (1.0 + r2)
    if PRESS_ON <= t < PRESS_OFF:
        d2 = (xs - PRESS_XY[0]) ** 2 + (ys - PRESS_XY[1]) ** 2
        img = img * np.where(d2 <= 10.0**2, 0.3, 1.0 - 0.5 * np.exp(-d2 / (2 * 14.0**2)))
    img = img + rng.normal(0.0, 1.5, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def write_press_recording(path: Path, seconds: float = 3.5, seed: int = 7) -> Path:
    rng = np.random.default_rng(seed)
    with RecordingWriter(path, name=path.name, width=WIDTH, height=HEIGHT, fps=FPS, roi=ROI) as writer:
        for i in range(int(seconds * FPS)):
            t = i / FPS
            writer.add_frame(t, frame(t, rng))
        path_rows = np.array([[PRESS_ON, *PRESS_XY], [PRESS_OFF, *PRESS_XY]])
        writer.set_labels(Labels("hold", False, PRESS_XY, (Contact(PRESS_ON, PRESS_OFF, path_rows),)))
    return path
