"""The debug view: a camera frame with the ROI, current contacts and their ids drawn.

Used by `feelium replay --annotate` and the daemon's debug stream, so a person
can see what the pipeline decided on every frame.
"""

from __future__ import annotations

import cv2
import numpy as np

from feelium.touch.pipeline import FrameResult

_FONT = cv2.FONT_HERSHEY_SIMPLEX
ROI_COLOR = (200, 160, 40)
CONTACT_COLOR = (40, 40, 230)
ACTIVE_COLOR = (40, 200, 240)


def draw_overlay(frame: np.ndarray, result: FrameResult, roi: tuple[int, int, int, int] | None) -> np.ndarray:
    """BGR copy of ``frame`` with the ROI, current contacts (circle sized by area, id) and frame scores."""
    if frame.ndim == 2:
        out = cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
    elif frame.shape[2] == 1:
        out = cv2.cvtColor(frame[:, :, 0], cv2.COLOR_GRAY2BGR)
    else:
        out = frame.copy()
    if roi is not None:
        x, y, w, h = roi
        color = ACTIVE_COLOR if result.activity else ROI_COLOR
        cv2.rectangle(out, (x, y), (x + w - 1, y + h - 1), color, 1)
    for contact in result.contacts:
        center = (int(round(contact.x)), int(round(contact.y)))
        radius = max(4, int(round(np.sqrt(max(contact.area, 1) / np.pi))))
        cv2.circle(out, center, radius, CONTACT_COLOR, 2, cv2.LINE_AA)
        cv2.drawMarker(out, center, CONTACT_COLOR, cv2.MARKER_CROSS, 10, 1)
        cv2.putText(out, f"#{contact.id}", (center[0] + radius + 3, center[1] - 3), _FONT, 0.5, CONTACT_COLOR, 1, cv2.LINE_AA)
    for event in result.events:
        if event.phase in ("down", "up"):
            text = f"{event.phase} #{event.id}" + (f" {event.kind}" if event.kind else "")
            cv2.putText(out, text, (int(event.x) + 8, int(event.y) + 16), _FONT, 0.45, (255, 255, 255), 1, cv2.LINE_AA)
    status = f"t={result.t:.2f}s anchor={result.anchor:.2f} depth={result.depth_max:.2f} area={result.area}"
    cv2.putText(out, status, (8, 18), _FONT, 0.5, (255, 255, 255), 1, cv2.LINE_AA)
    return out
