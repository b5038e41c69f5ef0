"""Drive the projector without the daemon, and say what it showed and when: what ``feelium record`` projects.

The projector is the rear camera's back-light, so a recording is only replayable if it keeps what was
projected (docs/recording-format.md: ``projector.mkv`` + ``projector_ts.txt``). On the blimp the daemon
owns the projector; ``feelium record`` runs with the daemon stopped and so must show something itself:
a flat back-light (the paper's condition), the default avatar talking, or a face video looped. This loop
renders each frame through the daemon's own :class:`Renderer` (the same map, sensing and fade floors), shows
it, and hands the frame with the time the display got it to a sink, on its own thread so the camera's
reading never waits for it.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from feelium.projector.display import Display
from feelium.projector.renderer import Renderer
from feelium.priority import name_current_thread

log = logging.getLogger(__name__)

CONTENTS = ("flat", "avatar", "face")
FLAT_LEVEL = 255  # the flat back-light is the projector at full white: the paper's static lit membrane

Sink = Callable[[float, np.ndarray], None]


class FaceVideo:
    """A video file's frames fitted to the canvas, read as they are due and looped at the file's end.

    Read on the fly, not decoded up front: a minute of face at the canvas size is ~0.4 GB, the board has 512 MB.
    """

    def __init__(self, path: Path, fit: Callable[[np.ndarray], np.ndarray]) -> None:
        self.path = path
        self._fit = fit
        self._capture = self._open()
        fps = self._capture.get(cv2.CAP_PROP_FPS)
        self.fps = float(fps) if fps and 1.0 <= fps <= 120.0 else 25.0
        self._index = -1
        self._frame: np.ndarray | None = None
        if self.at(0.0) is None:
            raise ValueError(f"{path}: no frame can be read from this video")

    def _open(self) -> cv2.VideoCapture:
        capture = cv2.VideoCapture(str(self.path))
        if not capture.isOpened():
            raise ValueError(f"{self.path}: OpenCV cannot open this video")
        return capture

    def at(self, t: float) -> np.ndarray | None:
        """The fitted frame due ``t`` seconds after the start (the last one read when the file lags behind)."""
        due = int(t * self.fps)
        while self._index < due:
            ok, image = self._capture.read()
            if not ok:  # the end: start again from the top
                self._capture.release()
                self._capture = self._open()
                ok, image = self._capture.read()
                if not ok:
                    break
            self._index += 1
            if self._index == due:
                self._frame = self._fit(image)
        return self._frame

    def close(self) -> None:
        self._capture.release()


class ShowLoop:
    """Renders, shows and reports projector frames at ``fps`` on its own thread until :meth:`stop`."""

    def __init__(
        self,
        renderer: Renderer,
        display: Display,
        *,
        fps: float,
        content: str = "avatar",
        face_video: Path | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        if content not in CONTENTS:
            raise ValueError(f"projector content must be one of {', '.join(CONTENTS)}, not {content!r}")
        if (content == "face") != (face_video is not None):
            raise ValueError("a face video is needed for the face content, and only for it")
        self.renderer = renderer
        self.display = display
        self.fps = fps
        self.content = content
        self.size = (renderer.config.width, renderer.config.height)
        self._clock = clock
        self._video = FaceVideo(face_video, renderer.fit_face) if face_video is not None else None
        self._flat = np.full((self.size[1], self.size[0], 3), FLAT_LEVEL, np.uint8)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.frames = 0
        self.late = 0
        self.error: BaseException | None = None  # what ended the loop early (kept: the caller reports it)

    def frame_at(self, t: float) -> np.ndarray:
        """The projector frame ``t`` seconds into the show."""
        if self.content == "flat":
            return self._flat
        face = self._video.at(t) if self._video is not None else None
        return self.renderer.render(t, face, (), talking=self.content == "avatar")

    def start(self, sink: Sink) -> None:
        """Start showing; ``sink(shown_at, frame)`` gets every frame with the clock's time the display got it."""
        self._thread = threading.Thread(target=self._run, args=(sink,), name="projector-show", daemon=True)
        self._thread.start()

    def _run(self, sink: Sink) -> None:
        name_current_thread()
        period = 1.0 / self.fps
        start = due = self._clock()
        try:
            while not self._stop.is_set():
                frame = self.frame_at(due - start)
                self.display.show(frame)
                sink(self._clock(), frame)
                self.frames += 1
                due += period
                wait = due - self._clock()
                if wait < 0:  # late: restart the schedule from now rather than rush to catch up
                    self.late += 1
                    due = self._clock()
                elif self._stop.wait(wait):
                    break
        except BaseException as exc:  # the camera's take goes on; the caller says the stream was cut
            self.error = exc
            log.error("projector show stopped: %s", exc)

    def stop(self) -> None:
        """Stop showing and wait for the thread (the last frame shown stays on the display)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        if self._video is not None:
            self._video.close()
