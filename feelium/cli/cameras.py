"""``feelium record`` (the live rear camera to a recording in format v1) and ``feelium calibrate lens``."""

from __future__ import annotations

import argparse
from typing import Any

from feelium.cli import CommandRegistry


def register(registry: CommandRegistry) -> None:
    rec = registry.command(
        "record",
        "Record the live rear camera (format v1) to collect real data on the blimp. SIGTERM, SIGINT (Ctrl-C) or "
        "SIGHUP end the take early and keep it (exit 0); a nearly full disk keeps a shorter take and exits 1.",
        _record,
    )
    rec.add_argument("--out", required=True, help="recording directory to create (must not exist)")
    rec.add_argument("--seconds", type=float, default=None, help="stop after this much camera time (default: until stopped)")
    rec.add_argument("--config", help="TOML config file ([rear_camera] chooses the camera)")
    rec.add_argument("--sim", action="store_true", help="record the scene simulator instead of the camera")
    rec.add_argument("--name", help="recording name (default: rec-<date>-<time>)")
    rec.add_argument("--session", default="", help="free text grouping recordings taken under the same conditions")
    rec.add_argument(
        "--projector",
        choices=("none", "flat", "avatar", "face"),
        default="none",
        help="what the projector shows while recording (the daemon must be stopped): none (leave it as it is), flat "
        "(full white: the paper's static back-light, no stream kept), avatar (the default face, talking) or face "
        "(--face-video looped); avatar and face keep the projector stream and the calibration in the take, so replay "
        "and eval predict the light as the daemon does (docs/recording-format.md)",
    )
    rec.add_argument("--face-video", metavar="FILE", help="with --projector face: the video to show (any file OpenCV reads)")
    lens = registry.subcommand(
        "calibrate", "lens",
        "Fit the front fisheye's lens model (OpenCV fisheye K, D) from views of a printed chessboard or ChArUco board "
        "and save it where the daemon serves it (GET /lens). Show the board, tilted, all over the image, edges included "
        "(a chessboard must be seen whole; a ChArUco board may hang over the edge).",
        _calibrate_lens,
    )  # fmt: skip
    lens.add_argument("source", nargs="?", help="a folder of images, a video file, or a recording (its camera.mkv)")
    lens.add_argument("--board", choices=("chessboard", "charuco"), default="chessboard",
                      help="the printed target (default chessboard); charuco counts partial views, near the rim too")
    lens.add_argument("--pattern", help="chessboard: inner corners COLSxROWS (default 9x6); "
                      "charuco: squares COLSxROWS (default 7x5)")
    lens.add_argument("--square-mm", type=float, help="printed square size in mm (sets no lens value; "
                      "default 25 for a chessboard, 35 for ChArUco)")
    lens.add_argument("--marker-mm", type=float, help="charuco: printed marker size in mm (default 0.75 of a square)")
    lens.add_argument("--dictionary", default="DICT_4X4_50", help="charuco: the ArUco dictionary (default DICT_4X4_50)")
    lens.add_argument("--write-board", metavar="PNG",
                      help="charuco: write the board to print (300 dpi, at --square-mm) and exit")
    lens.add_argument("--every", type=int, default=1, help="use every Nth image or frame (default 1)")
    lens.add_argument("--config", help="TOML config file; the lens is saved beside it ([front_camera] lens_file)")
    lens.add_argument("--out", help="where to save the lens JSON (default: [front_camera] lens_file; with --synthetic: not saved)")
    lens.add_argument("--synthetic", type=int, metavar="N",
                      help="instead of SOURCE, render N views through a known lens and report how well it is recovered")
    lens.add_argument("--save-views", metavar="DIR", help="with --synthetic: also write the rendered views as PNGs")
    lens.add_argument("--seed", type=int, default=1, help="with --synthetic: random poses seed")
    lens.add_argument("--json", action="store_true", help="print a machine-readable summary")


def _record(args: argparse.Namespace) -> int:
    import contextlib
    import dataclasses
    import logging
    import sys
    import threading
    import time
    from pathlib import Path

    from feelium.cameras.base import CameraUnavailable
    from feelium.cameras.record import default_name, record, stop_on_signals
    from feelium.daemon.assembly import rear_camera
    from feelium.daemon.backends import for_this_machine
    from feelium.daemon.config import load_config
    from feelium.daemon.journal import setup_logging
    from feelium.recording import recover_interrupted

    setup_logging(logging.INFO)
    config = load_config(args.config)
    if args.sim:
        config = dataclasses.replace(config, rear_camera=dataclasses.replace(config.rear_camera, backend="sim"))
    asked_auto = config.rear_camera.backend == "auto"
    config = for_this_machine(config)
    if args.seconds is not None and not args.seconds > 0:
        print("feelium record: --seconds must be positive", file=sys.stderr)
        return 2
    if args.face_video and args.projector != "face":
        print("feelium record: --face-video needs --projector face", file=sys.stderr)
        return 2
    out = Path(args.out)
    if out.parent.is_dir():  # takes a killed record (SIGKILL, power cut) left beside this one: finish them first
        for found in recover_interrupted(out.parent):
            print(f"feelium record: an interrupted take ({found.temp.name}): "
                  + (f"recovered {found.frames} frames as {found.path}" if found.path else "no frame reached the disk; removed"),
                  file=sys.stderr)  # fmt: skip
    if out.exists():
        print(f"feelium record: {out} already exists", file=sys.stderr)
        return 1
    try:
        source = rear_camera(config, time.monotonic)
        if source is None:
            print("feelium record: the rear camera is off in the config ([rear_camera] backend)", file=sys.stderr)
            return 1
        camera = source.open()
    except CameraUnavailable as exc:
        print(f"feelium record: {exc}", file=sys.stderr)
        return 1
    if source.backend == "sim" and asked_auto:  # asked for the camera, got the simulator: say so
        print("feelium record: recording the scene simulator (`auto` off a Raspberry Pi)", file=sys.stderr)
    show, files = None, {}
    if args.projector != "none":
        from feelium.daemon.assembly import build_show_loop

        try:
            video = Path(args.face_video) if args.face_video else None
            show, calibration = build_show_loop(config, args.projector, video, args.config)
        except (ValueError, OSError) as exc:
            camera.close()
            print(f"feelium record: --projector {args.projector}: {exc}", file=sys.stderr)
            return 1
        if calibration is not None and source.backend == "picamera2":
            files["projector-calibration.npz"] = calibration  # what replay and eval look for beside the trials
        elif calibration is not None:  # the simulated or replayed camera never sees the projector's light
            print(f"feelium record: the {source.backend} rear camera does not see the projector: showing "
                  f"{args.projector} without keeping its stream (replay would compensate light the frames never had)",
                  file=sys.stderr)  # fmt: skip
    name = args.name or default_name(time.time())
    shown = {"at": 0.0}

    def say(line: str, stream: Any) -> None:
        """A line to the terminal, which may be gone (a dropped SSH session): the take matters, not the line."""
        with contextlib.suppress(OSError):
            print(line, file=stream, flush=True)

    def progress(frames: int, t: float) -> None:
        if t - shown["at"] >= 5.0:
            shown["at"] = t
            say(f"{frames} frames, {t:.1f} s", sys.stderr)

    stop = threading.Event()
    lit_only = show is not None and not files  # the flat back-light: shown, not kept (nothing to predict)
    if lit_only:
        show.start(lambda _shown_at, _frame: None)
    try:
        with stop_on_signals(stop) as caught:
            take = record(
                camera,
                out,
                seconds=args.seconds,
                fps=config.rear_camera.fps,
                name=name,
                session=args.session,
                source="device" if source.backend == "picamera2" else "synthetic",
                extra_meta={"recorder": {"backend": source.backend, "config": dataclasses.asdict(config.rear_camera)}},
                stop=stop,
                on_frame=progress,
                projector=show if files else None,
                files=files,
            )
    except OSError as exc:  # the writer removed its temp dir: nothing half is left
        print(f"feelium record: cannot write {out}: {exc.strerror or exc}; nothing kept", file=sys.stderr)
        return 1
    except RuntimeError as exc:  # no first frame (a camera that delivers nothing): nothing was started
        print(f"feelium record: {exc}; nothing kept", file=sys.stderr)
        return 1
    finally:
        camera.close()
        if lit_only:
            show.stop()
    summary = f"{take.path} ({take.frames} frames, {take.seconds:.1f} s)"
    if take.projector_frames:
        summary += f", {take.projector_frames} projector frames"
    if take.projector_problem:
        say(f"feelium record: {take.projector_problem}; the take's projector stream is shorter than its camera's", sys.stderr)
    if take.ended == "disk full":
        say(f"feelium record: {take.problem} in {out.parent}: kept a shorter take {summary}", sys.stderr)
        return 1
    if take.ended == "camera stalled":
        say(f"feelium record: {take.problem}: kept a shorter take {summary}", sys.stderr)
        return 1
    say(f"recorded {summary}" + (f"; stopped by {caught[0]}" if caught else ""), sys.stdout)
    return 0


def _calibrate_lens(args: argparse.Namespace) -> int:
    import json
    import sys
    from pathlib import Path

    from feelium.cameras.lens import save_lens
    from feelium.lab.lens.calibrate import LensCalibrationError, calibrate, read_views

    try:
        board = _target(args)
        if args.write_board:
            return _write_board(board, Path(args.write_board))
        if args.synthetic:
            from feelium.lab.lens.synthetic import TRUTH, recovery_error, synthetic_views

            views = synthetic_views(TRUTH, board, args.synthetic, seed=args.seed)
            if args.save_views:
                _write_views(Path(args.save_views), views)
            result = calibrate(views, board)
        elif args.source:
            result = calibrate(read_views(args.source, max(1, args.every)), board)
        else:
            print("feelium calibrate lens: give a SOURCE (images, video or recording) or --synthetic N", file=sys.stderr)
            return 2
    except LensCalibrationError as exc:
        print(f"feelium calibrate lens: {exc}", file=sys.stderr)
        return 1
    summary = result.summary()
    if args.synthetic:
        summary["truth"] = TRUTH.to_json()
        summary["recovery_error"] = recovery_error(TRUTH, result.lens)
    out = _lens_out(args)
    if out is not None:
        summary["saved"] = str(save_lens(result.lens, out))
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        _print_lens(summary)
    return 0


def _target(args: argparse.Namespace):  # type: ignore[no-untyped-def]
    """The board the options describe (a ``LensCalibrationError`` names what is wrong)."""
    from feelium.lab.lens.calibrate import Board, CharucoBoard, LensCalibrationError

    if args.board == "chessboard":
        if args.write_board or args.marker_mm is not None:
            raise LensCalibrationError("--write-board and --marker-mm are for --board charuco")
        return Board.parse(args.pattern or "9x6", args.square_mm or 25.0)
    square = args.square_mm or 35.0
    return CharucoBoard.parse(args.pattern or "7x5", square, args.marker_mm or 0.75 * square, args.dictionary)


PRINT_DPI = 300


def _write_board(board, path: "Path") -> int:  # type: ignore[no-untyped-def]
    """The ChArUco board as a PNG to print at ``PRINT_DPI`` (then measure a square: that is ``--square-mm``)."""
    import sys

    import cv2

    px = round(board.square_m * 1000.0 / 25.4 * PRINT_DPI)
    margin = px // 4  # 7x5 squares of 35 mm then print 262 x 192 mm: inside an A4 page's printable area
    image = board.opencv.generateImage((board.cols * px + 2 * margin, board.rows * px + 2 * margin), marginSize=margin)
    if not cv2.imwrite(str(path), image, [cv2.IMWRITE_PNG_COMPRESSION, 9]):
        print(f"feelium calibrate lens: cannot write {path}", file=sys.stderr)
        return 1
    print(f"wrote {path}: {board.cols}x{board.rows} squares of {board.square_m * 1000:g} mm at {PRINT_DPI} dpi "
          f"({board.dictionary}); print at 100 %, measure a square and pass it as --square-mm")  # fmt: skip
    return 0


def _lens_out(args: argparse.Namespace) -> "Path | None":
    """Where to save: ``--out``, else (not for a synthetic run) the config's ``[front_camera] lens_file``."""
    from pathlib import Path

    if args.out:
        return Path(args.out)
    if args.synthetic:
        return None
    from feelium.daemon.config import load_config
    from feelium.skin.projector_map import calibration_path

    return calibration_path(load_config(args.config).front_camera.lens_file, args.config)


def _write_views(folder: "Path", views: list) -> None:
    import cv2

    folder.mkdir(parents=True, exist_ok=True)
    for i, (_, image) in enumerate(views):
        cv2.imwrite(str(folder / f"view-{i:02d}.png"), image)


def _print_lens(summary: dict) -> None:
    lens = summary["lens"]
    (fx, _, cx), (_, fy, cy), _ = lens["K"]
    print(f"views with the board: {summary['views_used']} (without: {summary['views_without_board']})")
    print(f"RMS reprojection error: {summary['rms_px']} px (worst view {summary['worst_view']}: {summary['worst_view_rms_px']} px)")
    print(f"{lens['width']}x{lens['height']}: fx {fx:.3f} fy {fy:.3f} cx {cx:.3f} cy {cy:.3f} D {[round(k, 6) for k in lens['D']]}")
    if "recovery_error" in summary:
        e = summary["recovery_error"]
        print(
            f"against the true lens: fx {e['fx_rel'] * 100:.3f} %, fy {e['fy_rel'] * 100:.3f} %, cx {e['cx_px']:.3f} px, "
            f"cy {e['cy_px']:.3f} px, D max {e['d_abs_max']:.5f}; projection within 80 degrees: "
            f"RMS {e['projection_px_rms']:.3f} px, max {e['projection_px_max']:.3f} px"
        )
    if "saved" in summary:
        print(f"saved {summary['saved']} (the daemon serves it at GET /lens after a restart)")
