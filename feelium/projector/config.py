"""The ``[projector]`` config section."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from feelium.settings import section, setting


@dataclass(frozen=True)
class CalibrationConfig:
    """Gray-code calibration of the camera-to-projector map (`feelium calibrate projector`)."""

    file: str = setting(
        "projector_calibration.npz",
        "Where the calibration map is saved and loaded; a relative path is taken beside the config file.",
    )
    block_px: int = setting(
        8, "Gray code resolves projector blocks of this many pixels (finer stripes blur away in the camera).", min=1, max=64
    )
    phase_period_px: int = setting(
        32, "Period of the phase-shift fringes that refine the Gray code to sub-pixel precision.", min=8, max=256
    )
    phase_steps: int = setting(8, "Phase shifts per axis (8 cancels projector gamma harmonics).", min=3, max=16)
    frames_per_pattern: int = setting(2, "Camera frames averaged per projected pattern.", min=1, max=16)
    settle_frames: int = setting(2, "Camera frames skipped after each pattern change (projector and exposure settle).", min=0, max=30)
    min_contrast: float = setting(
        10.0, "Least white-minus-black difference (grey levels) for a camera pixel to be decoded.", min=1.0, max=255.0
    )
    smooth_sigma_px: float = setting(
        1.5, "Gaussian smoothing (camera px) of the decoded map over covered pixels.", min=0.0, max=20.0
    )


@dataclass(frozen=True)
class ProjectorConfig:
    """Inner projector output and what it renders."""

    backend: Literal["auto", "fbdev", "window", "sim"] = setting(
        "auto",
        "Display output; auto is the framebuffer on a Raspberry Pi and sim elsewhere; window needs a GUI build of OpenCV.",
    )
    width: int = setting(1280, "Projector native width (Ultimems HD309: 1280).", min=16, max=7680)
    height: int = setting(720, "Projector native height (Ultimems HD309: 720).", min=16, max=4320)
    fps: float = setting(30.0, "Render rate.", min=1.0, max=120.0)
    answer_fps: float = setting(
        15.0,
        "Highest rate at which answers (ripples, glows, hearts) move on when nothing else changed: a frame shows "
        "them (and a growing stroke) at most 1/answer_fps old, a new face frame or a new or ended answer redraws "
        "at once, and a frame with nothing new is the previous one shown again (docs/performance.md). "
        "Set it to fps to animate every frame.",
        min=1.0,
        max=120.0,
    )
    face_cache_mb: float = setting(
        16.0,
        "Memory for the wearer's faces kept decoded, so a looping avatar's frames are decoded in its first two "
        "rounds only, not at every showing (a face is kept when it comes round again; 0.59 MB a face at the default "
        "canvas: 16 MB holds 27; frames beyond it are decoded each time round). 0 decodes every showing.",
        min=0.0,
        max=64.0,
    )
    fb_device: str = setting("/dev/fb0", "Linux framebuffer device of the fbdev backend.")
    canvas_width: int = setting(
        512, "Width of the skin canvas (the camera's sensitive patch) that layers are drawn on before warping.", min=16, max=4096
    )
    canvas_height: int = setting(384, "Height of the skin canvas.", min=16, max=4096)
    warp_resolution: Literal["optics", "full"] = setting(
        "optics",
        "optics: warp the canvas onto the coarsest grid (1/2, 2/3 or all of the projector's pixels per axis) that "
        "still has a sample per canvas pixel, then scale it up bilinearly (the membrane's blur hides the second "
        "interpolation; docs/projector.md); full: remap every projector pixel.",
    )
    gamma: float = setting(2.2, "Projector gamma: light output ~ (value / 255) ^ gamma.", min=1.0, max=3.0)
    black_level: float = setting(
        0.03, "Light a black projector pixel still gives, relative to white (predicts the back-light).", min=0.0, max=0.5
    )
    flat_level: float = setting(
        0.85,
        "Grey level (0..1) of the flat projection the touch reference corresponds to; back-light gain 1.0 means this.",
        min=0.05,
        max=1.0,
    )
    sensing_floor: float = setting(
        0.45,
        "Darkest grey (0..1) projected on the sensitive patch: the projector is the touch sensor's back-light, "
        "and a skin projected near black is blind (the camera sees too little light to find a shadow).",
        min=0.0,
        max=1.0,
    )
    fade_floor: float = setting(
        0.75,
        "Least mean grey (0..1) of the sensitive patch: when the picture goes dark as a whole (a fade of the "
        "wearer's video), it is lifted until its mean is this, so a press is still seen (taps in a black fade: "
        "4/12 at the sensing floor alone, 12/12 at 0.75); a face at full brightness is above it. 0 turns it off.",
        min=0.0,
        max=1.0,
    )
    diffusion_px: float = setting(
        0.7, "Membrane diffusion of projected light, in camera px, for the back-light prediction.", min=0.0, max=30.0
    )
    probe: Literal["auto", "on", "off"] = setting(
        "auto",
        "The touch probe, a faint checkerboard pulsing at 2 Hz that teaches touch the projector's share of the "
        "membrane's light in a lit room (docs/projector.md, The probe): auto lays it while the skin shows no moving "
        "wearer video (the avatar, a still face: nothing touch could learn from), on always, off never.",
    )
    calibration: CalibrationConfig = section(CalibrationConfig)
