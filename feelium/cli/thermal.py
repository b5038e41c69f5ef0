"""`feelium thermal read|decode`, `feelium bench thermal` and `feelium bench presence`."""

from __future__ import annotations

import argparse
import json
import sys

from feelium.cli import CommandRegistry


def register(registry: CommandRegistry) -> None:
    read = registry.subcommand(
        "thermal", "read", "Show live thermal frames as a terminal heat map (check the wiring in seconds).", _read
    )
    read.add_argument("--frames", type=int, default=0, help="stop after N images (each new sub-page updates half the pixels; default: until Ctrl-C)")
    read.add_argument("--sim", action="store_true", help="use the simulated sensor instead of the I2C bus")
    read.add_argument("--config", help="TOML config file (default: built-in defaults)")
    read.add_argument("--colors", choices=("auto", "truecolor", "256"), default="auto", help="terminal colour mode")
    read.add_argument("--timeout", type=float, default=5.0, help="give up after this long without a frame (s)")

    decode = registry.subcommand(
        "thermal", "decode", "Turn raw MLX90640 words (eeprom, ram in a .npz) into object temperatures.", _decode
    )
    decode.add_argument("input", metavar="IN.npz", help="npz with eeprom (832,) and ram (N, 834) uint16, optional t (N,)")
    decode.add_argument("--out", metavar="OUT.npz", help="write t, celsius (N, 24, 32), eeprom and ram here")
    decode.add_argument("--json", action="store_true", help="print Vdd, Ta and the extracted calibration as JSON")
    decode.add_argument("--emissivity", type=float, default=None, help="override [thermal] emissivity")
    decode.add_argument("--config", help="TOML config file (default: built-in defaults)")

    bench = registry.subcommand(
        "bench", "thermal", "Decode speed: vectorised numpy against per-pixel Python, same frames, same run.", _bench
    )
    bench.add_argument("--repeats", type=int, default=200, help="frames timed for the vectorised decoder")
    bench.add_argument("--baseline-repeats", type=int, default=20, help="frames timed for the per-pixel baseline")
    bench.add_argument("--json", metavar="PATH", help="also write the result as JSON here ('-' for stdout)")

    presence = registry.subcommand(
        "bench", "presence", "Presence on simulated approach/leave and empty clips: detection, false alarms, latency.",
        _bench_presence,
    )
    presence.add_argument("--approach", type=int, default=60, help="number of approach clips")
    presence.add_argument("--empty", type=int, default=6, help="number of empty-room clips")
    presence.add_argument("--empty-seconds", type=float, default=1800.0, help="length of each empty clip (s)")
    presence.add_argument("--seed", type=int, default=0)
    presence.add_argument(
        "--room-c", type=float, nargs=2, metavar=("LOW", "HIGH"), default=(19.0, 26.0),
        help="room temperatures drawn from this range (degC; a warm room leaves bodies little contrast)",
    )
    presence.add_argument(
        "--through-driver", action="store_true",
        help="frames go simulated sensor -> I2C transport -> driver -> decoder, as in the daemon (about 4 ms a sub-page)",
    )
    presence.add_argument("--config", help="TOML config file (its [thermal.presence] is evaluated)")
    presence.add_argument("--json", metavar="PATH", help="also write the report as JSON here ('-' for stdout)")


def _write_json(path: str | None, obj: object) -> None:
    if not path:
        return
    text = json.dumps(obj, indent=2)
    if path == "-":
        print(text)
    else:
        with open(path, "w", encoding="utf-8") as f:
            f.write(text + "\n")


def _read(args: argparse.Namespace) -> int:
    import time

    import numpy as np

    from feelium.daemon.config import load_config
    from feelium.hub import Hub
    from feelium.thermal.calibration import CalibrationError
    from feelium.thermal.decoder import FrameAssembler
    from feelium.thermal.heatmap import render
    from feelium.thermal.service import sim_driver, smbus2_driver

    from feelium.daemon.backends import for_this_machine

    loaded = load_config(args.config)
    config = for_this_machine(loaded)
    cfg = config.thermal
    sim = args.sim or cfg.backend == "sim"
    if sim and not args.sim and loaded.thermal.backend == "auto":  # asked for the sensor, got the simulator: say so
        print("feelium thermal read: the simulated sensor (`auto` off a Raspberry Pi)", file=sys.stderr)
    try:
        driver = sim_driver(cfg, Hub(), config.sim.seed) if sim else smbus2_driver(cfg)
        calibration = driver.start()
    except (OSError, CalibrationError) as exc:
        where = "the simulated bus" if sim else f"/dev/i2c-{cfg.i2c_bus} address 0x{cfg.i2c_address:02X}"
        print(f"feelium thermal read: no sensor on {where}: {exc}", file=sys.stderr)
        if isinstance(exc, FileNotFoundError):
            print("the I2C bus is not enabled: dtparam=i2c_arm=on in /boot/firmware/config.txt, reboot", file=sys.stderr)
        elif isinstance(exc, PermissionError):
            print("no access to the I2C device: add the user to the i2c group (or run as root)", file=sys.stderr)
        print(f"check wiring (SDA, SCL, 3.3 V, GND), `i2cdetect -y {cfg.i2c_bus}`, or try --sim", file=sys.stderr)
        return 1
    assembler = FrameAssembler(calibration, cfg.emissivity, cfg.reflected_offset_c)
    truecolor = None if args.colors == "auto" else args.colors == "truecolor"
    tty = sys.stdout.isatty()
    shown = 0
    last_frame_at = time.monotonic()
    times: list[float] = []
    try:
        while args.frames <= 0 or shown < args.frames:
            try:
                words = driver.poll()
            except OSError as exc:
                print(f"I2C error (retrying): {exc}", file=sys.stderr)
                time.sleep(0.1)
                continue
            now = time.monotonic()
            if words is None:
                if now - last_frame_at > args.timeout:
                    print(f"feelium thermal read: no frame for {args.timeout:.0f} s: {driver.health()}", file=sys.stderr)
                    return 1
                time.sleep(0.25 / cfg.refresh_hz)
                continue
            image = assembler.add(words)
            if image is None or not assembler.complete:
                continue
            last_frame_at = now
            times.append(now)
            times = times[-20:]
            rate = f"{(len(times) - 1) / (times[-1] - times[0]):4.1f}" if len(times) > 1 and times[-1] > times[0] else "  --"
            sub = assembler.last
            finite = image[np.isfinite(image)]
            lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (float("nan"), float("nan"))
            header = (
                f"min {lo:5.1f} C  max {hi:5.1f} C  Ta {sub.ta:5.1f} C  Vdd {sub.vdd:4.2f} V  "
                f"{rate} sub-pages/s  rejected {sum(assembler.rejected.values())}"
            )
            if tty and shown:
                sys.stdout.write("\x1b[13A")  # redraw in place: header + 12 lines
            sys.stdout.write(header + "\x1b[K\n" + render(image, truecolor=truecolor) + "\n")
            sys.stdout.flush()
            shown += 1
    finally:
        driver.close()
    return 0


def _decode(args: argparse.Namespace) -> int:
    import numpy as np

    from feelium.daemon.config import load_config
    from feelium.thermal.calibration import CalibrationError, extract_calibration
    from feelium.thermal.decoder import FrameAssembler

    cfg = load_config(args.config).thermal
    emissivity = cfg.emissivity if args.emissivity is None else args.emissivity
    try:
        with np.load(args.input) as data:
            if "eeprom" not in data or "ram" not in data:
                print(f"{args.input}: needs arrays 'eeprom' (832,) and 'ram' (N, 834); has {sorted(data.files)}", file=sys.stderr)
                return 1
            eeprom = np.asarray(data["eeprom"])
            ram = np.asarray(data["ram"])
            t = np.asarray(data["t"], dtype=np.float64) if "t" in data else np.arange(len(ram), dtype=np.float64)
    except (OSError, ValueError) as exc:
        print(f"{args.input}: cannot read: {exc}", file=sys.stderr)
        return 1
    if ram.ndim != 2 or ram.shape[1] != 834 or len(t) != len(ram):
        print(f"{args.input}: ram must be (N, 834) with t (N,); got {ram.shape} and {t.shape}", file=sys.stderr)
        return 1
    if eeprom.dtype.kind not in "iu" or ram.dtype.kind not in "iu":
        print(f"{args.input}: eeprom and ram must hold integer words", file=sys.stderr)
        return 1
    try:
        calibration = extract_calibration(eeprom)
    except CalibrationError as exc:
        print(f"{args.input}: bad EEPROM: {exc}", file=sys.stderr)
        return 1
    assembler = FrameAssembler(calibration, emissivity, cfg.reflected_offset_c)
    celsius = np.full((len(ram), 24, 32), np.nan, dtype=np.float32)
    per_frame = []
    for i, words in enumerate(ram):
        image = assembler.add(words)
        if image is not None:
            celsius[i] = image
            per_frame.append({"i": i, "subpage": assembler.last.subpage, "vdd": assembler.last.vdd, "ta": assembler.last.ta})
    if args.out:
        np.savez_compressed(args.out, t=t, celsius=celsius, eeprom=eeprom.astype(np.uint16), ram=ram.astype(np.uint16))
    summary = {
        "frames": int(len(ram)),
        "decoded": assembler.decoded,
        "rejected": dict(assembler.rejected),
        "nan_pixels": assembler.failed_pixels,
        "emissivity": emissivity,
        "frames_detail": per_frame,
        "calibration": calibration.summary(),
    }
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        finite = celsius[np.isfinite(celsius)]
        span = f"{finite.min():.2f}..{finite.max():.2f} degC" if finite.size else "no valid pixel"
        print(f"{args.input}: {len(ram)} frames, {assembler.decoded} decoded, rejected {dict(assembler.rejected)}, {span}"
              + (f" -> {args.out}" if args.out else ""))
    return 0 if assembler.decoded else 1


def _bench(args: argparse.Namespace) -> int:
    from feelium.lab.thermal.bench import format_table, run_bench

    result = run_bench(args.repeats, args.baseline_repeats)
    print(format_table(result))
    _write_json(args.json, result)
    return 0


def _bench_presence(args: argparse.Namespace) -> int:
    from feelium.daemon.config import load_config
    from feelium.lab.thermal.evaluation import evaluate_presence

    cfg = load_config(args.config).thermal
    report = evaluate_presence(
        approach=args.approach, empty=args.empty, empty_s=args.empty_seconds, seed=args.seed, config=cfg.presence,
        fps=cfg.refresh_hz, room_c=(args.room_c[0], args.room_c[1]),
        through_driver=args.through_driver,
    )
    lat, leave = report["approach_latency_ms"] or {}, report["leave_latency_ms"] or {}
    via = "simulated sensor + driver + decoder" if report["through_driver"] else "renderer"
    print(f"frames from the {via}; room {report['room_c'][0]:.1f}..{report['room_c'][1]:.1f} degC; approach clips {report['clips']['approach']}, detected {report['detection_rate']:.3f} {report['by_kind']}")
    print(f"false alarms: {report['false_alarms_per_hour']} per hour over {report['clips']['empty_hours']} h of empty room, "
          f"{report['false_alarms_in_approach_clips']} before a body moved")
    at = report["detected_at_mm"] or {}
    print(f"approach latency vs entering {report['near_mm']:.0f} mm: median {lat.get('median')} ms, p95 {lat.get('p95')} ms"
          f" (negative = noticed earlier); body at {at.get('median')} mm (median), {at.get('max')} mm (farthest) when noticed")
    print(f"leave latency vs leaving {report['near_mm']:.0f} mm: median {leave.get('median')} ms, p95 {leave.get('p95')} ms")
    _write_json(args.json, report)
    return 0
