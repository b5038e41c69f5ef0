"""`feelium bench touch` replays a recording that carries its projector stream as `eval` does: with the light
predicted from the stream (a compensated path is what gets timed and scored), and skips one with no map."""

from __future__ import annotations

import numpy as np

from feelium.lab.touch import bench
from feelium.lab.touch.recorded_light import CALIBRATION_FILE
from feelium.projector.config import ProjectorConfig
from feelium.recording import Labels, RecordingWriter
from feelium.skin.projector_map import DEFAULT_CAMERA_SIZE, DEFAULT_ROI, default_calibration
from feelium.touch.config import TouchConfig


def _take(folder):
    w, h = DEFAULT_CAMERA_SIZE
    writer = RecordingWriter(folder / "s1" / "empty-001", name="empty-001", width=w, height=h, fps=10.0, roi=DEFAULT_ROI)
    config = ProjectorConfig()
    writer.set_projector(config.width, config.height, 10.0)
    for k in range(6):
        writer.add_projector_frame(k / 10.0 - 0.05, np.full((config.height, config.width), 200, np.uint8))
        writer.add_frame(k / 10.0, np.full((h, w), 150, np.uint8))
    writer.set_labels(Labels("empty", False, None, ()))
    writer.close()
    return config


def test_a_recording_with_its_stream_is_replayed_with_the_predicted_light_and_skipped_without_a_map(tmp_path, monkeypatch, capsys):
    config = _take(tmp_path)
    lights = []
    real = bench.replay_recording

    def spy(recording, touch, **kw):
        lights.append(kw.get("light"))
        return real(recording, touch, **kw)

    monkeypatch.setattr(bench, "replay_recording", spy)
    variants = bench.build_variants(TouchConfig(), resolutions=((320, 240),))
    bench.run_variants(tmp_path, variants)
    assert lights == [] and "skipped" in capsys.readouterr().err  # a stream and no map: named, not replayed blind
    default_calibration(DEFAULT_CAMERA_SIZE, DEFAULT_ROI, (config.width, config.height)).save(tmp_path / CALIBRATION_FILE)
    bench.run_variants(tmp_path, variants)
    assert len(lights) == len(variants) and all(light is not None for light in lights)
    # The prediction is timed apart from the pipeline, and the Pi's frame rate counts both.
    row = bench.summarise(tmp_path, variants, DEFAULT_CAMERA_SIZE)["variants"][1]
    light_ms, cpu_ms = row["light_cpu_ms_per_frame"]["median"], row["cpu_ms_per_frame"]["median"]
    assert light_ms > 0.0 and cpu_ms > 0.0
    assert row["pi_fps_at_10x"] < 100.0 / cpu_ms
