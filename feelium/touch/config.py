"""The ``[touch]`` config section: every parameter of the shadow pipeline.

Distances are in camera pixels of the input frame (the pipeline scales them to
its working resolution), times in seconds of the camera clock, depths are
relative shadow depth (0 = full back-light, 1 = none left).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from feelium.settings import setting
from feelium.skin.face import FACE_AZIMUTH_DEG, FACE_ELEVATION_DEG


@dataclass(frozen=True)
class TouchConfig:
    """Rear-camera shadow pipeline (reference, depth, gates, fingertip, tracker)."""

    width: int = setting(
        320,
        "Working resolution width for the whole camera frame; the ROI is cut out and resized by the same factor.",
        min=32,
        max=4096,
    )
    height: int = setting(240, "Working resolution height for the whole camera frame.", min=24, max=4096)
    detect_scale: float = setting(
        0.5,
        "Fraction of the working resolution the per-pixel work (reference, depth, compensation, candidates) runs at; "
        "below 1 each frame with a candidate finds its fingertips again at the working resolution in a window around "
        "the shadows (0.5: 4x fewer pixels, what fits the Pi; 1.0: the whole working image, ~1.6x the CPU; "
        "docs/touch.md, *Detection at half resolution*).",
        min=0.25,
        max=1.0,
    )

    # Reference and exposure.
    reference_tau_s: float = setting(
        4.0, "Time constant of the reference where no shadow is seen (slow adaptation).", min=0.05, max=3600.0
    )
    reference_bright_tau_s: float = setting(
        0.5,
        "Faster time constant where the membrane got brighter than the reference (a shadow cannot brighten).",
        min=0.01,
        max=3600.0,
    )
    reference_forced_tau_s: float = setting(
        90.0,
        "Very slow forced update under a shadow that is not anchored, so the reference never freezes forever.",
        min=1.0,
        max=1e6,
    )
    dark_reference_level: float = setting(
        12.0, "Reference brightness (grey levels) below which a pixel is masked: too dark to divide by.", min=0.5, max=254.0
    )
    saturation_level: int = setting(
        250, "Frame value at or above which a pixel is masked as saturated.", min=1, max=255
    )
    rebaseline_gain_step: float = setting(
        0.12,
        "Relative jump of the exposure gain between frames that counts as a lighting step and re-baselines.",
        min=0.01,
        max=10.0,
    )
    reference_margin_px: float = setting(
        4.0,
        "Darkened regions are widened by this much (camera px) before freezing the reference, so penumbras never creep in.",
        min=0.0,
        max=200.0,
    )
    row_gain_clip: float = setting(
        0.12,
        "Per-row gain (laser banding against the rolling shutter) is measured with ratios clipped to 1 +- this; 0 disables.",
        min=0.0,
        max=1.0,
    )
    gain_sample_step: int = setting(
        3, "Sample every n-th pixel (each axis) for the robust exposure-gain median.", min=1, max=32
    )

    # Depth, activity and candidates.
    blur_sigma_px: float = setting(
        2.0, "Gaussian smoothing of the depth map before segmentation (camera px).", min=0.0, max=50.0
    )
    noise_floor: float = setting(
        0.07, "Smoothed depth above which a pixel counts as darkened (activity, reference masking).", min=0.0, max=1.0
    )
    noise_sigmas: float = setting(
        4.0,
        "The darkening floor is at least this many times the measured noise of the smoothed depth (dim, noisy sessions).",
        min=0.0,
        max=100.0,
    )
    activity_min_area_px: int = setting(
        200, "Darkened area (camera px, specks removed) a frame needs to raise the activity flag.", min=1, max=10_000_000
    )
    candidate_depth: float = setting(
        0.15, "Smoothed depth a connected shadow must exceed to become a candidate.", min=0.0, max=1.0
    )
    candidate_min_area_px: int = setting(
        25, "Smallest candidate shadow (camera px above candidate_depth).", min=1, max=10_000_000
    )
    max_candidates: int = setting(6, "Largest candidates considered per frame (by area).", min=1, max=64)
    core_fraction: float = setting(
        0.75, "The darkening core is where depth >= this fraction of the candidate's peak depth.", min=0.05, max=0.99
    )
    contact_split_fraction: float = setting(
        0.5,
        "Parts of one shadow's core are separate contacts (two fingertips in one hand's shadow) when its depth "
        "between them falls below this fraction of the core's mean depth: a pressed contact blurred by the membrane's scatter "
        "is at half its depth at its edge, so below half the skin between them is not on the membrane. 0: never split.",
        min=0.0,
        max=0.99,
    )

    # Contact shape (finger, palm, hug), see docs/touch.md "Contact shape".
    px_per_mm: float = setting(
        2.0,
        "Camera pixels (of the input frame) per mm on the membrane, for contact areas and axes in mm; the nominal "
        "640x480 rear camera over the front face. 0: unknown (figures in mm are null, classification assumes 2.0).",
        min=0.0,
        max=1000.0,
    )
    palm_min_area_mm2: float = setting(
        1500.0,
        "Contact footprint (mm^2) from which it is a palm: above a thumb pressed hard (4 cm^2) or two fingers "
        "together (8 cm^2), below the heel of a palm alone (about 16 cm^2).",
        min=1.0,
        max=1e7,
    )
    hug_min_area_mm2: float = setting(
        20000.0,
        "Contact footprint (mm^2) from which it is a hug or lean-in: more than the whole palmar side of a large "
        "adult hand (180-200 cm^2).",
        min=1.0,
        max=1e8,
    )
    hug_min_length_mm: float = setting(
        230.0,
        "A palm-sized footprint at least this long (mm) is a hug too (a forearm along the skin): longer than any "
        "hand, wrist to fingertip 17-21 cm.",
        min=1.0,
        max=1e5,
    )

    contact_edge_radius_px: float = setting(
        20.0,
        "Search radius (camera px) around a shadow's core (a fingertip's pad, a pressed palm) for its steepest edge.",
        min=1.0,
        max=500.0,
    )

    # Gates.
    contact_edge: float = setting(
        0.046,
        "Steepest depth gradient near the fingertip (depth per camera px) from which its shadow has a contact edge: "
        "skin on the membrane casts a shadow as sharp as the membrane's scatter, a hover's is blurred by its height. "
        "Both gates need it; 0 turns the test off (the paper's gates alone).",
        min=0.0,
        max=1.0,
    )
    instant_depth: float = setting(
        0.55, "Instant gate: a core at least this deep is a firm press.", min=0.0, max=1.0
    )
    anchor_window_s: float = setting(
        1.0,
        "Sustained-anchoring window: rolling minimum of core depth over this much camera time, counted from when the "
        "shadow landed (showed a contact edge).",
        min=0.05,
        max=30.0,
    )
    anchor_threshold: float = setting(
        0.30, "Sustained gate: rolling minimum core depth at or above this is an anchored touch.", min=0.0, max=1.0
    )
    anchor_min_age_s: float = setting(
        0.5, "The sustained gate needs a shadow landed (with a contact edge) at least this long.", min=0.0, max=30.0
    )
    release_depth: float = setting(
        0.25, "While down, a contact stays down as long as its core is at least this deep (hysteresis).", min=0.0, max=1.0
    )
    release_edge_fraction: float = setting(
        0.75,
        "While down, a contact also needs an edge of at least this fraction of contact_edge (hysteresis): a finger "
        "lifted to hover just above the skin releases, so two pats with a brief lift between stay two.",
        min=0.0,
        max=1.0,
    )

    # Tracker.
    match_distance_px: float = setting(
        60.0, "Largest centre jump (camera px) for a candidate to continue a track between frames.", min=1.0, max=10000.0
    )
    down_frames: int = setting(
        2, "Consecutive touching frames that confirm a touch (debouncing of the onset).", min=1, max=100
    )
    release_s: float = setting(
        0.15, "A down contact not touching for this long is released (debouncing of the release).", min=0.0, max=10.0
    )
    move_min_px: float = setting(
        2.0, "Fingertip displacement (camera px) since the last reported position that emits a move.", min=0.0, max=1000.0
    )
    hold_min_s: float = setting(0.6, "Contacts at least this long (and not swipes) are holds.", min=0.0, max=60.0)
    swipe_min_path_px: float = setting(
        40.0, "Fingertip path length (camera px) from which a contact is a swipe.", min=0.0, max=100000.0
    )
    path_deadband_px: float = setting(
        3.0, "Fingertip jitter below this (camera px) does not add to the path length.", min=0.0, max=1000.0
    )

    # Projected content (the face on the skin), see docs/touch.md "Projected content".
    projected_response_tau_s: float = setting(
        20.0,
        "Time constant of the per-pixel projector-to-camera response learned online from frames without hands.",
        min=0.5,
        max=3600.0,
    )
    projected_prior_var: float = setting(
        0.01,
        "Variance of the predicted light a pixel must have seen before its own gain outweighs the global one.",
        min=1e-6,
        max=10.0,
    )
    contact_projected_depth: float = setting(
        0.2,
        "Where the projector's share of the light is known (learned from projected content or the probe, "
        "feelium/touch/roomshare.py), a contact must take at least this fraction of the projector's own light away "
        "at its deepest point: a hand above the membrane only blocks light from outside (room and returned light), "
        "skin on it also frustrates the projector's reflection (0.4-0.5 of it). Half the weakest; 0 turns it off.",
        min=0.0,
        max=1.0,
    )
    projector_share_tau_s: float = setting(
        5.0,
        "Time constant (s) over which the projector's share of the light is learned per coarse tile.",
        min=0.1,
        max=3600.0,
    )
    projector_latency_s: float = setting(
        0.033,
        "Projector frame clock to light on the membrane (s): which projector frames a camera exposure integrated.",
        min=0.0,
        max=1.0,
    )
    projector_latency_sigma_s: float = setting(
        0.0167,
        "How far the projector latency may be off (s; half a 30 fps frame, the scan-out phase): the prediction's "
        "per-pixel spread over it is the depth a prediction error could fake, taken off every shadow.",
        min=0.0,
        max=1.0,
    )
    camera_exposure_s: float = setting(
        0.03, "Rear camera exposure time (s) over which the projected light is mixed.", min=0.0, max=1.0
    )

    # The whole front face, see docs/touch.md "The whole front face" (defaults: feelium/skin/face.py).
    face_model: Literal["none", "sphere"] = setting(
        "none",
        "none: the sensitive patch is the camera ROI and u, v run 0..1 across it; sphere: the whole curved front "
        "face (the face_* geometry, a fisheye filling the frame), u, v are azimuth and elevation on the envelope "
        "and the projector's skin canvas uses the same u, v.",
    )
    face_radius_mm: float = setting(320.0, "Envelope radius (mm; the 64 cm blimp).", min=1.0, max=10000.0)
    face_camera_behind_mm: float = setting(
        240.0, "The rear camera sits on the front axis this far behind the sphere's centre (mm; < face_radius_mm).",
        min=0.0, max=10000.0,
    )  # fmt: skip
    face_azimuth_deg: float = setting(
        FACE_AZIMUTH_DEG, "The face's extent in azimuth around the front axis (deg); also what GET /lens tells the headset "
        "(skin_patch_deg), with or without the face model.", min=1.0, max=179.0)
    face_elevation_deg: float = setting(
        FACE_ELEVATION_DEG, "The face's extent in elevation (deg); GET /lens serves it too.", min=1.0, max=179.0)

    def __post_init__(self) -> None:
        # Checked here so a bad geometry is a config error at load, not a crash when the first frame arrives.
        if self.face_camera_behind_mm >= self.face_radius_mm:
            raise ValueError(
                f"face_camera_behind_mm ({self.face_camera_behind_mm}) must be less than face_radius_mm ({self.face_radius_mm}): "
                "the rear camera is inside the envelope"
            )
