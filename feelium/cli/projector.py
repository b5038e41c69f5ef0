"""Commands of the projector: `feelium calibrate projector` and `feelium bench projector`."""

from __future__ import annotations

import argparse
import json
import sys

from feelium.cli import CommandRegistry


def register(registry: CommandRegistry) -> None:
    cal = registry.subcommand(
        "calibrate", "projector",
        "Project Gray-code and phase patterns, decode them in the rear camera, save the camera-to-projector map; "
        "or fit it offline from a calibration RECORDING.",
        _calibrate,
    )
    cal.add_argument(
        "recording", nargs="?",
        help="fit offline from this recording (an empty scene whose projector stream shows structured light: "
        "decoded from the recorded frames, the project's own sequence or binary patterns with their inverses)",
    )  # fmt: skip
    cal.add_argument("--record", metavar="DIR", help="also write the run as a calibration recording here (to fit again offline)")
    cal.add_argument(
        "--session", default="projector-calibration",
        help="--record: the recording's session, that of the trials it calibrates (replay and eval prefer a calibration "
        "recording of a trial's own session among those beside it)",
    )  # fmt: skip
    cal.add_argument("--config", help="TOML config file; the map is saved beside it (projector.calibration.file)")
    cal.add_argument("--sim", action="store_true", help="run against the scene simulator's known warp and report the error to the truth")
    cal.add_argument("--json", action="store_true", help="print a machine-readable summary")
    cal.add_argument("--out", help="where to save the map (default: beside the config)")
    cal.add_argument("--seed", type=int, default=1, help="simulator seed (--sim)")
    bench = registry.subcommand("bench", "projector", "Render time per frame at the projector's resolution on one core.", _bench)
    bench.add_argument("--config", help="TOML config file")
    bench.add_argument("--frames", type=int, default=90, help="frames per measurement")
    bench.add_argument("--stream-seconds", type=float, default=10.0, help="seconds of the realistic frame stream, full vs tiled warp")
    bench.add_argument("--json", help="also write the report to this JSON file")
    face = registry.subcommand(
        "bench", "projector-facevideo",
        "Does a moving projected face fool the touch sensor? Touch pipeline on simulated trials: flat projection, "
        "face video, face video with back-light prediction.",
        _bench_facevideo,
    )
    face.add_argument("--config", help="TOML config file (its [projector] and [touch] sections are used)")
    face.add_argument("--scale", type=float, default=0.1, help="share of the protocol's 228 trials (0 < scale <= 1)")
    face.add_argument("--seed", type=int, default=1, help="simulator seed")
    face.add_argument("--jobs", type=int, default=1, help="worker processes")
    face.add_argument("--json", help="also write the report to this JSON file")


def _calibrate(args: argparse.Namespace) -> int:
    from pathlib import Path

    import numpy as np

    from feelium.daemon.config import load_config
    from feelium.lab.projector.calibrate import run_calibration, truth_error
    from feelium.skin.projector_map import calibration_path

    config = load_config(args.config)
    projector = config.projector
    size = (projector.width, projector.height)
    truth = None
    if args.sim:
        from feelium.sim.projection import FisheyeWarp, ProjectedLight, SimPatternCapture
        from feelium.sim.scene import HEIGHT, WIDTH, Session

        warp = FisheyeWarp()
        light = ProjectedLight(warp, (WIDTH, HEIGHT))
        capture = SimPatternCapture(Session("projector-calibration"), light, np.random.default_rng(args.seed))
        truth = warp.truth_map(*capture.camera_size)
    if args.recording:
        from feelium.lab.projector.from_recording import calibrate_recording
        from feelium.recording import Recording, RecordingError

        try:
            result = calibrate_recording(
                Recording(Path(args.recording)), projector.calibration, config.touch.projector_latency_s, config.touch.camera_exposure_s
            )
        except (RecordingError, ValueError) as exc:
            print(f"feelium calibrate projector: {exc}", file=sys.stderr)
            return 1
    else:
        device = None if args.sim else _device_capture(config)
        live = capture if device is None else device
        recorder = None
        if args.record:
            from feelium.lab.projector.from_recording import RecordingCapture

            recorder = live = RecordingCapture(
                live, Path(args.record), size, config.rear_camera.fps, session=args.session,
                source="synthetic" if device is None else "device",
            )
        try:
            result = run_calibration(live, projector.calibration, size, source="sim" if device is None else "device")
        finally:
            if recorder is not None:
                print(f"calibration recording: {recorder.close()}", file=sys.stderr)
            if device is not None:
                device.close()
    summary = dict(result.summary)
    summary["source"] = result.calibration.source
    if result.calibration.latency_s is not None:  # what to set on the blimp, by the rule replay and eval follow
        from feelium.touch.projected import touch_with_latency

        touch = touch_with_latency(config.touch, result.calibration)
        summary["latency"] = {**summary["latency"], "touch_keys": {
            "projector_latency_s": round(touch.projector_latency_s, 4),
            "projector_latency_sigma_s": round(touch.projector_latency_sigma_s, 4),
        }}  # fmt: skip
    if truth is not None:
        summary["truth_error_px"] = truth_error(result.calibration, *truth)
    out = Path(args.out) if args.out else calibration_path(config.projector.calibration.file, args.config)
    summary["saved"] = str(result.calibration.save(out))
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        _print_summary(summary)
    return 0 if summary["coverage"] > 0 else 1


def _print_summary(summary: dict) -> None:
    def stats(name: str, s: dict) -> str:
        return f"{name}: median {s['median']} px, p95 {s['p95']} px, max {s['max']} px"

    print(f"coverage of the sensitive patch: {summary['coverage'] * 100:.1f} % ({summary['patterns']} patterns)")
    print(stats("fit residual (projector px)", summary["fit_residual_px"]))
    print(stats("round trip camera->projector->camera (camera px)", summary["roundtrip_px"]))
    if "truth_error_px" in summary:
        t = summary["truth_error_px"]
        print(stats("error to the simulator's true map (projector px)", t) + f", within 1 px: {t['within_1px'] * 100:.2f} %")
    latency = summary.get("latency")
    if latency is not None and latency["measured"]:
        keys = ", ".join(f"{k} = {v}" for k, v in latency["touch_keys"].items())
        print(
            f"projector latency: {latency['latency_ms']} ms +- {latency['uncertainty_ms']} ms (spread {latency['spread_ms']} ms over "
            f"{latency['straddling_frames']} frames straddling a switch, exposure {latency['exposure_ms']} ms from the "
            f"{latency['exposure_from']}); kept in the map, which the daemon, replay and eval use; a map kept elsewhere needs "
            f"in [touch]: {keys}"
        )
    elif latency is not None:
        print(f"projector latency: not measured, {latency['reason']}; the map used the config's {latency['assumed_ms']} ms")
    print(f"saved {summary['saved']}")


class _DeviceCapture:
    """Patterns on the real projector (display backend), frames from the real rear camera."""

    def __init__(self, display, camera, camera_size, roi) -> None:
        self._display = display
        self._camera = camera
        self.camera_size = camera_size
        self.roi = roi
        self.last_t = 0.0

    def show(self, pattern) -> None:
        import cv2

        self._display.show(cv2.cvtColor(pattern, cv2.COLOR_GRAY2BGR))

    def capture(self):
        frame = self._camera.read()
        if frame is None:
            raise RuntimeError("the rear camera stopped delivering frames during calibration")
        self.last_t = frame.t  # the camera's own time, for a calibration recording (--record)
        return frame.image

    def close(self) -> None:
        self._camera.close()
        self._display.close()


def _device_capture(config) -> _DeviceCapture:
    import time

    from feelium.daemon.assembly import rear_camera
    from feelium.daemon.backends import for_this_machine
    from feelium.projector.display import FbdevDisplay

    source = rear_camera(for_this_machine(config), time.monotonic)
    if source is None or source.backend != "picamera2":
        print(
            "feelium: calibrate projector needs the real rear camera and projector (use --sim to run against the simulator)",
            file=sys.stderr,
        )
        raise SystemExit(1)
    display = FbdevDisplay(config.projector.fb_device)
    camera = source.open()
    first = camera.read()
    if first is None:
        raise RuntimeError("the rear camera delivered no frame")
    h, w = first.image.shape[:2]
    return _DeviceCapture(display, camera, (w, h), first.roi)


def _bench(args: argparse.Namespace) -> int:
    from pathlib import Path

    import numpy as np

    from feelium.daemon.config import load_config
    from feelium.lab.projector.bench import format_table, run_bench
    from feelium.skin.projector_map import ProjectorMap
    from feelium.sim.projection import FisheyeWarp

    from feelium.daemon.memory import tune_malloc

    whole = load_config(args.config)
    config = whole.projector
    tune_malloc(whole.daemon.malloc_arenas, whole.daemon.malloc_mmap_threshold_kb)  # allocations cost what they do in `feelium run`
    camera, roi = (640, 480), (64, 48, 512, 384)
    px, py = FisheyeWarp().truth_map(*camera)
    x, y, w, h = roi
    outside = np.ones(px.shape, bool)
    outside[y : y + h, x : x + w] = False
    px[outside] = np.nan
    py[outside] = np.nan
    calibration = ProjectorMap(camera, (config.width, config.height), roi, px, py, source="sim fisheye warp")
    report = run_bench(config, calibration, frames=args.frames, stream_s=args.stream_seconds)
    print(format_table(report))
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=2) + "\n")
    return 0


def _bench_facevideo(args: argparse.Namespace) -> int:
    from pathlib import Path

    from feelium.daemon.config import load_config
    from feelium.lab.projector.facevideo import format_table, run_experiment

    if not 0.0 < args.scale <= 1.0:
        print(f"feelium: --scale must be in (0, 1], got {args.scale}", file=sys.stderr)
        return 2
    config = load_config(args.config)

    def progress(n: int, total: int, name: str) -> None:
        print(f"\r{n}/{total} {name:<40}", end="", file=sys.stderr, flush=True)

    report = run_experiment(
        scale=args.scale, seed=args.seed, projector=config.projector, touch=config.touch, jobs=max(1, args.jobs), progress=progress
    )
    print(file=sys.stderr)
    print(format_table(report))
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=2) + "\n")
    verdict = report["verdict"]
    return 0 if verdict["fp_trials_not_above_flat"] and verdict["recall_within_2_points"] else 1
