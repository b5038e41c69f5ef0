"""The ``[rear_camera]`` and ``[front_camera]`` config sections."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from feelium.settings import setting


def check_roi(roi: tuple[int, ...], width: int, height: int, key: str = "roi") -> None:
    """An ROI is empty (whole frame) or ``[x, y, w, h]`` inside the frame."""
    if not roi:
        return
    if len(roi) != 4:
        raise ValueError(f"{key} must be [x, y, w, h] or [], got {list(roi)}")
    x, y, w, h = roi
    if w <= 0 or h <= 0 or x < 0 or y < 0 or x + w > width or y + h > height:
        raise ValueError(f"{key} {list(roi)} does not fit the {width}x{height} frame")


@dataclass(frozen=True)
class RearCameraConfig:
    """The rear (touch) camera inside the envelope."""

    backend: Literal["auto", "picamera2", "replay", "sim", "off"] = setting(
        "auto", "Frame source; auto is picamera2 on a Raspberry Pi (a missing camera fails loudly) and sim elsewhere; off runs no touch sensing."
    )
    replay_path: str = setting("", "Recording (or dataset directory) for the replay backend.")
    replay_realtime: bool = setting(True, "Replay at the recording's own pace; false = as fast as the pipeline runs.")
    replay_loop: bool = setting(True, "Start the replay again when it ends (a demo that keeps going).")
    replay_projector_calibration: str = setting(
        "",
        "Projector map (a file saved by `feelium calibrate projector`) for replayed recordings that carry their"
        " projector stream; \"\" = the one beside each recording (projector-calibration.npz), as replay and eval find it.",
    )
    camera_index: int = setting(0, "picamera2 camera number of the rear (IMX500) camera.", min=0, max=7)
    fps: float = setting(15.0, "Frame rate asked of the camera (and of the simulator).", min=1.0, max=120.0)
    roi: tuple[int, ...] = setting(
        (), "Sensitive skin patch [x, y, w, h] in working-resolution pixels; [] = whole frame (picamera2 only)."
    )
    settle_s: float = setting(
        2.0, "Seconds of auto exposure/white balance before they are locked (the reference needs fixed exposure).",
        min=0.0, max=30.0,
    )
    debug_video_fps: float = setting(
        5.0, "Rate of annotated rear frames (touch overlay) published for the debug view; 0 = none.", min=0.0, max=60.0
    )
    stale_after_s: float = setting(
        2.0, "Health reports the touch pipeline degraded when no rear frame was processed for this long.",
        min=0.1, max=60.0,
    )
    projection_compensation: Literal["auto", "on", "off"] = setting(
        "auto",
        "Divide the predicted back-light of what the projector shows out of each frame, so a moving face is not a"
        " touch; auto = on with the real camera (picamera2) when a projector calibration exists, and for a replayed"
        " recording that carries its projector stream (predicted from the recorded frames, not the live projector's)."
        " Simulated frames and replays without a stream do not contain the projector's light; off = never.",
    )

    def __post_init__(self) -> None:
        if self.roi and (len(self.roi) != 4 or self.roi[2] <= 0 or self.roi[3] <= 0 or min(self.roi) < 0):
            raise ValueError(f"rear_camera.roi must be [x, y, w, h] with positive size or [], got {list(self.roi)}")


@dataclass(frozen=True)
class FrontCameraConfig:
    """The front fisheye camera: the wearer's eyes."""

    backend: Literal["auto", "picamera2", "v4l2", "replay", "sim", "off"] = setting(
        "auto", "Frame source; auto on a Raspberry Pi is picamera2 or a USB (v4l2) camera, never sim; elsewhere sim."
    )
    camera_index: int = setting(1, "picamera2 camera number of the front (fisheye) camera.", min=0, max=7)
    device: str = setting("/dev/video0", "V4L2 device of a USB front camera.")
    replay_path: str = setting("", "Recording whose camera.mkv is played as the front view (replay backend).")
    width: int = setting(640, "Frame width delivered to the headset.", min=32, max=4096)
    height: int = setting(480, "Frame height delivered to the headset.", min=24, max=4096)
    fps: float = setting(15.0, "Frame rate.", min=1.0, max=120.0)
    jpeg: Literal["auto", "hardware", "software"] = setting(
        "auto",
        "Who encodes the headset's JPEGs: hardware = the camera's own encoder, forwarded without decoding (almost"
        " no ARM CPU): on picamera2 the VideoCore's (fails where there is none, e.g. a Pi 5), on a USB (v4l2) camera"
        " its MJPEG, Huffman tables inserted where it leaves them out (fails when it gives no MJPEG at width x"
        " height); software = the daemon (OpenCV); auto = hardware where the camera offers it, else software (logged"
        " once). replay and sim always encode in software.",
    )
    lens_file: str = setting(
        "front_lens.json",
        "The fisheye's lens model (OpenCV fisheye K, D) written by `feelium calibrate lens` and served at GET /lens;"
        " a relative path is taken beside the config file. Missing: an uncalibrated 180-degree stand-in (the sim"
        " backend always serves its own exact lens).",
    )
