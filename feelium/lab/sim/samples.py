"""The small sample recordings committed in ``recordings/``: simulated protocol trials, cut short.

A full simulated trial is 4 s of 640x480 lossless video (about 11 MB: the
camera's noise does not compress). The samples keep the contact and enough
hand-free frames before it for the adaptive reference and the gates to start
(``LEAD_S``), so the repository stays a few MB and the end-to-end tests replay
a fixed artefact in the recording format rather than only what today's
simulator writes.

``python -m feelium.lab.sim.samples recordings`` writes them again (same seed,
same frames: the simulator is deterministic).
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

from feelium.lab.sim.protocol import plan, write_item
from feelium.recording import Recording, RecordingWriter, ThermalData

SEED = 7
SCALE = 0.02  # the smallest plan that has one trial of each label
LEAD_S = 0.45  # hand-free frames kept before the first contact (or either side of the middle of a negative)
TAIL_S = 0.15  # frames kept after the last contact
SAMPLES = {"s1/s1-tap-001": "tap", "s1/s1-hover-001": "hover"}


def window(recording: Recording) -> tuple[float, float]:
    """The span of camera time a sample keeps."""
    contacts = recording.labels.contacts if recording.labels is not None else ()
    if contacts:
        return contacts[0].t_on - LEAD_S, contacts[-1].t_off + TAIL_S
    middle = float(recording.timestamps[len(recording.timestamps) // 2])
    return middle - LEAD_S, middle + LEAD_S


def cut(source: Recording, out: Path) -> Path:
    """Write the part of ``source`` inside :func:`window` as a new recording at ``out``."""
    t0, t1 = window(source)
    meta = source.meta
    extra = {k: v for k, v in meta.raw.items() if k not in ("format", "version", "name", "session", "source", "camera", "roi", "thermal")}
    extra["sample"] = {"cut_from": meta.name, "window_s": [round(t0, 4), round(t1, 4)]}
    with RecordingWriter(out, name=f"sample-{meta.name}", width=meta.camera.width, height=meta.camera.height,
                         fps=meta.camera.fps, session=meta.session, source=meta.source, roi=meta.roi,
                         extra_meta=extra, overwrite=True) as writer:  # fmt: skip
        for t, frame in source.frames():
            if t0 <= t <= t1:
                writer.add_frame(t, frame)
        if source.labels is not None:
            writer.set_labels(source.labels)
        thermal = source.thermal()
        if thermal is not None and meta.thermal is not None:
            keep = (thermal.t >= t0) & (thermal.t <= t1)
            writer.set_thermal(ThermalData(t=thermal.t[keep], celsius=thermal.celsius[keep], eeprom=thermal.eeprom,
                                           ram=None if thermal.ram is None else thermal.ram[keep]), meta.thermal["fps"])  # fmt: skip
    return out


def write_samples(out_dir: Path) -> list[Path]:
    """Render the sampled trials (only those) and write their cuts under ``out_dir``, one folder per label."""
    items = {item.relpath: item for item in plan(SCALE)}
    written = []
    with tempfile.TemporaryDirectory() as tmp:
        for relpath, label in SAMPLES.items():
            full = write_item(items[relpath], Path(tmp), SEED, SCALE)
            written.append(cut(Recording(full), out_dir / label))
    return written


if __name__ == "__main__":
    for path in write_samples(Path(sys.argv[1] if len(sys.argv) > 1 else "recordings")):
        print(path)
