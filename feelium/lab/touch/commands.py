"""The work behind `feelium replay`, `feelium eval` and `feelium calibrate touch`."""

from __future__ import annotations

import argparse
import io
import json
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from feelium.daemon.config import load_config
from feelium.lab.plot import Series, line_plot
from feelium.recording import NEGATIVE_LABELS, Recording, RecordingError, find_recordings
from feelium.lab.touch.skips import Skips
from feelium.lab.touch.zones import ZONES
from feelium.lab.touch.calibrate import ClipSeries, Fit, fit_edge, fit_gates, fit_projected
from feelium.touch.config import TouchConfig
from feelium.lab.touch.evaluate import ClipData, TrialData, build_report
from feelium.lab.touch.margins import GateSeries, GateThresholds
from feelium.lab.touch.contact_score import score_contacts
from feelium.lab.touch.light_report import LightRecord, SwitchRecord, light_rows, light_summary, switch_summary
from feelium.lab.touch.recorded_light import recorded_light
from feelium.lab.touch.switch_recovery import recoveries
from feelium.lab.touch.replay import ReplayResult, face_of, relative_name, replay_recording
from feelium.projector.config import ProjectorConfig


def _calibration(args: argparse.Namespace) -> Path | None:
    given = getattr(args, "projector_calibration", None)
    return Path(given) if given else None


# -- replay ------------------------------------------------------------------------------


def run_replay(args: argparse.Namespace) -> int:
    whole = load_config(args.config)
    config = whole.touch
    root = Path(args.path)
    paths = find_recordings(root)
    dataset = not (len(paths) == 1 and paths[0].resolve() == root.resolve())
    annotate = Path(args.annotate) if args.annotate else None
    out = sys.stdout
    skips = Skips("replay")
    for recording in skips.recordings(root):
        name = relative_name(root, recording.path)
        writer = None
        on_frame = None
        if annotate is not None:
            target = annotate / f"{name.replace('/', '__')}.mp4" if dataset else annotate
            writer = _VideoOut(target, recording.meta.camera.fps, (recording.meta.camera.width, recording.meta.camera.height))
            on_frame = writer.frame_hook(recording.meta.roi)
        try:
            result = skips.attempt(
                lambda: replay_recording(
                    recording, config, on_frame=on_frame,
                    light=recorded_light(recording, root, whole.projector, config, _calibration(args)),
                )
            )  # fmt: skip
        finally:
            if writer is not None:
                writer.close()
        if result is None:
            continue
        for event in result.events:
            obj = event.to_json()
            if dataset:
                obj["recording"] = name
            out.write(json.dumps(obj) + "\n")
        out.flush()
    return skips.finish()


class _VideoOut:
    """An annotated video for people: MP4 (mp4v) where FFmpeg can, else MJPEG AVI."""

    def __init__(self, path: Path, fps: float, size: tuple[int, int]) -> None:
        import cv2

        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self._writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, size)
        if not self._writer.isOpened():
            self.path = path.with_suffix(".avi")
            self._writer = cv2.VideoWriter(str(self.path), cv2.VideoWriter_fourcc(*"MJPG"), fps, size)
        if not self._writer.isOpened():
            raise OSError(f"{path}: cannot write a video here")

    def frame_hook(self, roi: tuple[int, int, int, int] | None):
        from feelium.touch.overlay import draw_overlay

        def hook(t: float, frame: np.ndarray, result: Any) -> None:
            self._writer.write(draw_overlay(frame, result, roi))

        return hook

    def close(self) -> None:
        self._writer.release()
        print(f"annotated video: {self.path}", file=sys.stderr)


# -- calibrate ---------------------------------------------------------------------------


def clip_frames(t: np.ndarray) -> np.ndarray:
    """The frames of a clip that belong to it: from 0 s on. Frames before 0 s are a recorded warm-up (the
    simulator's hand-free seconds that teach the reference, docs/touch.md): the pipeline sees them, but they
    are neither the clip's hover nor part of its time span, which the fit/hold-out split divides."""
    inside = t >= 0.0
    return inside if inside.any() else np.ones(t.size, bool)


def _clip_series(result: ReplayResult) -> ClipSeries:
    labels = result.recording.labels
    assert labels is not None
    keep = clip_frames(result.t)
    t = result.t[keep]
    contact = np.zeros(t.size, bool)
    for c in labels.contacts:
        contact |= (t >= c.t_on) & (t < c.t_off)
    return ClipSeries(
        labels.label, t, result.anchor[keep], result.core_depth[keep], result.edge[keep], contact, result.projected_depth[keep]
    )


def fit_on_clips(
    recordings: list[Recording],
    config: TouchConfig,
    skips: Skips,
    *,
    root: Path | None = None,
    projector: ProjectorConfig | None = None,
    calibration: Path | None = None,
) -> Fit:
    """Fit the landing gates first (the contact edge and the projected-light gate: neither score depends on a
    threshold), then replay the clips with them and fit the depth thresholds.

    A clip recorded with its projector stream (``feelium record --projector``) is replayed with the light the
    daemon would predict, as ``eval`` does (the map from ``calibration``, else the one beside it under
    ``root``): fitted blind to the face, the gates would be another pipeline's. A clip whose video turns out
    bad while replaying, or that has a stream and no map, is reported through ``skips`` and left out.
    """
    optics = projector or ProjectorConfig()

    def replay(recording: Recording, touch: TouchConfig) -> ReplayResult:
        top = root if root is not None else recording.path.parent
        return replay_recording(recording, touch, light=recorded_light(recording, top, optics, touch, calibration))

    first: list[tuple[Recording, ReplayResult]] = []
    for r in recordings:
        if r.labels is not None and r.labels.clip and r.labels.label in ("contact", "hover"):
            result = skips.attempt(lambda: replay(r, config))
            if result is not None:
                first.append((r, result))
    if not first:
        raise ValueError("no continuous contact/hover clips in this dataset (labels with \"clip\": true)")
    series = [_clip_series(result) for _, result in first]
    edge = fit_edge(series, held_frames=config.down_frames)
    projected = fit_projected(series, config.contact_projected_depth, held_frames=config.down_frames)
    landing = replace(config, contact_edge=edge.threshold, contact_projected_depth=projected.threshold)
    return fit_gates([_clip_series(replay(r, landing)) for r, _ in first], edge, projected)


def run_calibrate(args: argparse.Namespace) -> int:
    whole = load_config(args.config)
    config = whole.touch
    skips = Skips("calibrate touch", scores_labels=True)
    root = Path(args.dataset)
    try:
        fit = fit_on_clips(list(skips.recordings(root)), config, skips, root=root, projector=whole.projector,
                           calibration=_calibration(args))  # fmt: skip
    except ValueError as exc:
        print(f"feelium calibrate touch: {exc}", file=sys.stderr)
        return 1
    text = fit.to_toml()
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(text, encoding="utf-8")
        print(f"wrote {args.out}: " + ", ".join(f"{k} = {v}" for k, v in fit.values().items()))
        for line in fit.summary():
            print(line)
    else:
        sys.stdout.write(text)
    for warning in fit.warnings:
        print(f"feelium calibrate touch: warning: {warning}", file=sys.stderr)
    return skips.finish()


# -- eval --------------------------------------------------------------------------------


def scoring_input(root: Path, result: ReplayResult) -> TrialData | ClipData:
    """What scoring needs from one replayed, labelled recording: a trial, or a continuous clip's series."""
    labels = result.recording.labels
    assert labels is not None
    if labels.clip:
        keep = clip_frames(result.t)
        return ClipData(labels, result.t[keep], result.anchor[keep], result.core_depth[keep], result.edge[keep])
    return TrialData(
        name=relative_name(root, result.recording.path),
        labels=labels,
        events=result.events,
        activity=bool(result.activity.any()),
        max_area=float(result.area.max()) if result.area.size else 0.0,
        series=GateSeries(
            result.t, result.anchor, result.core_depth, result.edge, labels.contacts, labels.label in NEGATIVE_LABELS,
            result.projected_depth,
        ),
        face=face_of(result.recording),
    )


def condition_of(root: Path, recording: Recording) -> str:
    """The condition a recording was made under: its ``meta.generator.condition`` (``feelium simulate condition``),
    else the first folder under the dataset root (a real dataset laid out by condition), else ``"."``."""
    generator = recording.meta.raw.get("generator")
    named = generator.get("condition") if isinstance(generator, dict) else None
    if isinstance(named, str) and named:
        return named
    try:
        parts = recording.path.resolve().relative_to(root.resolve()).parts
    except ValueError:
        return "."
    return parts[0] if len(parts) > 1 else "."


def evaluate_dataset(
    root: Path,
    config: TouchConfig,
    *,
    dataset_name: str | None = None,
    plain: bool = False,
    skips: Skips | None = None,
    by_condition: bool = False,
    paper_gates: bool = False,
    projector: ProjectorConfig | None = None,
    calibration: Path | None = None,
):
    """Replay every good labelled recording under ``root`` and build the report; returns (report, clips).

    A recording with a projector stream is replayed with the light the daemon would predict from it
    (:mod:`feelium.lab.touch.recorded_light`: ``projector``'s optics, the ``calibration`` map, else the one
    beside the trials).

    Bad recordings are reported through ``skips`` and left out (a fresh :class:`Skips` when not given). With
    ``by_condition`` the report gains ``"conditions"``: the same report for each condition's recordings alone
    (:func:`condition_of`), a key the evaluation spec allows beside its own.

    With ``paper_gates`` every recording is also replayed as the paper's detector (:func:`paper_config`: its
    two gates alone, no contact edge, and blind to the projected light, which the paper did not predict) and
    the report, and each condition's, gains ``"paper_gates"``: the same report for that detector, so what the
    project's additions buy (or cost) is read per condition on the same frames.
    """
    skips = skips if skips is not None else Skips("eval", scores_labels=True)
    ours = _Groups()
    paper = _Groups()
    paper_cfg = paper_config(config)
    for recording in skips.recordings(root):
        if recording.labels is None:
            continue
        result = skips.attempt(
            lambda: replay_recording(
                recording, config, plain=plain,
                light=recorded_light(recording, root, projector or ProjectorConfig(), config, calibration),
            )
        )  # fmt: skip
        if result is None:
            continue
        condition = condition_of(root, recording) if by_condition else "."
        switch = SwitchRecord(
            *recoveries(
                recording, config, lambda: recorded_light(recording, root, projector or ProjectorConfig(), config, calibration)
            )
        )  # it replayed above: its light and frames are good
        ours.add(condition, root, result, switch)
        blind = skips.attempt(lambda: replay_recording(recording, paper_cfg, plain=plain)) if paper_gates else None
        if blind is not None:
            paper.add(condition, root, blind)
    if not ours.groups:
        raise RecordingError(root, "holds no labelled recording to evaluate")
    name = dataset_name or str(root)
    report, all_clips = ours.report(name, config, by_condition)
    if paper_gates:
        report["paper_gates"], _ = paper.report(name, paper_cfg, by_condition)
        for condition, sub in report.get("conditions", {}).items():
            sub["paper_gates"] = report["paper_gates"]["conditions"][condition]
        report["paper_gates"].pop("conditions", None)
    return report, all_clips


def paper_config(config: TouchConfig) -> TouchConfig:
    """The paper's detector within this pipeline: its instant and sustained-anchoring gates alone.

    ``contact_edge = 0`` makes every seen shadow count as landed (:mod:`feelium.touch.gates`), so nothing but
    the two gates decides; replayed without a light feed, it is also blind to the projected light, as the
    paper was. The front end (reference, depth, candidates) stays the project's: the comparison isolates the
    decision and the light, not the image processing.
    """
    return replace(config, contact_edge=0.0)


class _Group:
    """One condition's scoring inputs: trials, clips, timings, and the light's records (added keys)."""

    def __init__(self) -> None:
        self.trials: list[TrialData] = []
        self.clips: list[ClipData] = []
        self.timings: list[np.ndarray] = []
        self.light: list[LightRecord] = []
        self.switches: list[SwitchRecord] = []


class _Groups:
    """Scoring inputs grouped by condition, and the report built from them."""

    def __init__(self) -> None:
        self.groups: dict[str, _Group] = {}

    def add(self, condition: str, root: Path, result: ReplayResult, switch: SwitchRecord | None = None) -> None:
        group = self.groups.setdefault(condition, _Group())
        group.timings.append(result.seconds_per_frame)
        group.light.append(LightRecord.of(result))
        if switch is not None and switch.switches.times:
            group.switches.append(switch)
        item = scoring_input(root, result)
        (group.clips if isinstance(item, ClipData) else group.trials).append(item)  # type: ignore[arg-type]

    def report(self, name: str, config: TouchConfig, by_condition: bool) -> tuple[dict[str, Any], list[ClipData]]:
        gates = GateThresholds(
            config.contact_edge, config.instant_depth, config.anchor_threshold, config.anchor_min_age_s,
            config.contact_projected_depth,
        )

        def report_of(title: str, group: _Group) -> dict[str, Any]:
            seconds = np.concatenate(group.timings) if group.timings else np.zeros(0)
            report = build_report(title, group.trials, group.clips, seconds, config.width, config.height, gates)
            report["contacts"] = score_contacts(group.trials, config.px_per_mm or 2.0)  # added key: several contacts
            report["light"] = light_summary(group.light)  # added keys: health's verdict, recovery after a switch
            report["switch_recovery"] = switch_summary(group.switches)
            return report

        every = _Group()
        for group in self.groups.values():
            for key, values in vars(group).items():
                getattr(every, key).extend(values)
        report = report_of(name, every)
        if by_condition:
            report["conditions"] = {title: report_of(title, self.groups[title]) for title in sorted(self.groups)}
        return report, every.clips


def run_eval(args: argparse.Namespace) -> int:
    whole = load_config(args.config)
    config = whole.touch
    root = Path(args.dataset)
    fitted: dict[str, float] | None = None
    fit_warnings: list[str] = []
    fit_notes: list[str] = []
    if args.fit_on_clips:
        try:
            # quiet: the scoring pass below meets the same bad recordings and reports them once
            fitting = Skips("eval", err=io.StringIO(), scores_labels=True)
            fit = fit_on_clips(list(fitting.recordings(root)), config, fitting, root=root, projector=whole.projector,
                               calibration=_calibration(args))  # fmt: skip
        except ValueError as exc:
            print(f"feelium eval: --fit-on-clips: {exc}", file=sys.stderr)
            return 1
        fitted = fit.values()
        config = replace(config, **fitted)
        fit_warnings, fit_notes = fit.warnings, fit.notes
        for note in fit_notes:
            print(f"feelium eval: --fit-on-clips: {note}", file=sys.stderr)
        for warning in fit_warnings:
            print(f"feelium eval: --fit-on-clips: warning: {warning}", file=sys.stderr)
    skips = Skips("eval", scores_labels=True)
    report, clips = evaluate_dataset(
        root, config, dataset_name=args.dataset, skips=skips, by_condition=args.by_condition,
        paper_gates=args.paper_gates, projector=whole.projector, calibration=_calibration(args),
    )  # fmt: skip
    report["touch_config"] = {
        "fitted_on_clips": fitted is not None,
        "fit_warnings": fit_warnings,
        "fit_notes": fit_notes,
        "contact_edge": config.contact_edge,
        "contact_projected_depth": config.contact_projected_depth,
        "instant_depth": config.instant_depth,
        "anchor_threshold": config.anchor_threshold,
        "anchor_window_s": config.anchor_window_s,
        "width": config.width,
        "height": config.height,
    }
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
    figure = Path(args.figure) if args.figure else (
        Path(args.json).with_name(Path(args.json).stem + "-anchoring.png") if args.json else Path("touch-anchoring.png")
    )
    drawn = write_anchoring_figure(figure, clips, report["sustained"]["threshold"])
    print(format_report(report))
    for name, sub in report.get("conditions", {}).items():
        print(f"\n== condition {name}")
        print(format_report(sub))
    if "paper_gates" in report:
        print("\n== the paper's two gates alone (no contact edge, blind to the projected light), beside this pipeline")
        print(format_comparison(report))
    if drawn:
        print(f"figure: {figure}")
    if args.json:
        print(f"report: {args.json}")
    return skips.finish()


def write_anchoring_figure(path: Path, clips: list[ClipData], threshold: float | None) -> bool:
    """The paper's figure: anchoring score over time on the contact and hover clips, with the fitted threshold."""
    series = []
    for label in ("contact", "hover"):
        for clip in clips:
            if clip.labels.label == label and clip.t.size:
                series.append(Series(clip.t - clip.t[0], clip.anchor, f"{label} clip"))
                break
    if not series:
        return False
    hlines = [(threshold, f"fitted threshold {threshold:.2f}")] if threshold is not None else []
    line_plot(
        path,
        series,
        title="Sustained-anchoring score on the continuous clips",
        xlabel="time in clip (s)",
        ylabel="anchoring score",
        hlines=hlines,
    )
    return True


def _fmt(value: Any, digits: int = 3) -> str:
    if value is None:
        return "n/a"
    if isinstance(value, float):
        return f"{value:.{digits}f}"
    return str(value)


def _margin_rows(margins: dict[str, Any] | None) -> list[tuple[str, str]]:
    """One row per gate and sample: hardest negative and positive scores, each with its margin to the threshold."""
    rows: list[tuple[str, str]] = []
    for sample in ("trials", "clips"):
        gates = (margins or {}).get(sample)
        if not gates:
            continue
        for gate, m in gates.items():
            rows.append(
                (
                    f"margins {sample}, {gate}",
                    f"threshold {m['threshold']:.3f}: hardest negative {_fmt(m['hardest_negative'])} "
                    f"({_signed(m['negative_margin'])}), hardest positive {_fmt(m['hardest_positive'])} "
                    f"({_signed(m['positive_margin'])})",
                )
            )
    return rows


def _contact_rows(c: dict[str, Any] | None) -> list[tuple[str, str]]:
    """Several contacts per trial (labels saying what touched): ids, and what touched against the truth."""
    if not c:
        return []
    err = c["error_px"]
    kinds = "; ".join(f"{k}: " + ", ".join(f"{n} {got}" for got, n in v.items() if n) for k, v in c["kinds"].items())
    return [
        ("contacts (several per trial)", f"{c['contacts']} in {c['trials']} trials: {c['touches']} touches, missed {c['missed']}, "
         f"split {c['split']}, id swaps {c['swaps']}, phantoms {c['phantoms']}"),
        ("  contact kind right", f"{c['kind_right']} of {c['kind_scored']} ({kinds})"),
        ("  gesture right (per contact)", f"{c['gesture_right']} of {c['gesture_scored']} ("
         + "; ".join(f"{k}: " + ", ".join(f"{n} {got}" for got, n in v.items() if n) for k, v in c["gestures"].items())
         + ")"),
        ("  error px (median/max)", "n/a" if err is None else f"{err['median']:.2f} / {err['max']:.2f}"),
        *(
            (f"  footprint on up, {kind}", f"n {f['n']}: {_fmt(f['area_mm2'], 1)} mm^2, {_fmt(f['major_mm'], 1)} x "
             f"{_fmt(f['minor_mm'], 1)} mm, elongation {_fmt(f['elongation'], 1)} (medians)")
            for kind, f in c.get("footprint", {}).items()
        ),
    ]  # fmt: skip


def _zone_rows(zones: dict[str, Any] | None) -> list[tuple[str, str]]:
    """One row per zone of the front face: recall, negatives fired, localisation error (none without a face)."""
    if zones is None:
        return []
    rows = [("by face zone", "recall, negatives fired, error px (median/p95)")]
    for zone in ZONES:
        z = zones[zone]
        if z is None:
            rows.append((f"  {zone}", "no trials"))
            continue
        err = z["localisation"]["error_px"]
        rows.append(
            (
                f"  {zone}",
                f"{_fmt(z['recall'])} ({z['tp']} of {z['tp'] + z['fn']}), {z['fp']} of {z['fp'] + z['tn']} fired, "
                + ("n/a" if err is None else f"{err['median']:.2f} / {err['p95']:.2f}"),
            )
        )
    if zones["unplaced"]:
        rows.append(("  unplaced", f"{zones['unplaced']} trials (no labelled point, e.g. hovers, or off the face)"))
    return rows


def _outcome(report: dict[str, Any]) -> str:
    """Precision / recall, negatives fired and the localisation median of one report, in one cell."""
    t = report["trials"]
    error = report["localisation"]["error_px"]
    return (
        f"{_fmt(t['precision'])} / {_fmt(t['recall'])}, {t['fp']} of {t['fp'] + t['tn']} negatives fired, "
        f"{'n/a' if not error else format(error['median'], '.2f')} px"
    )


def format_comparison(report: dict[str, Any]) -> str:
    """Per condition (and overall), this pipeline against the paper's two gates alone on the same frames."""
    rows = [("all recordings", report)] + list(report.get("conditions", {}).items())
    width = max(len(name) for name, _ in rows)
    lines = [f"{'condition':<{width}}  this pipeline | the paper's two gates"]
    for name, sub in rows:
        lines.append(f"{name:<{width}}  {_outcome(sub)} | {_outcome(sub['paper_gates'])}")
    return "\n".join(lines)


def _signed(value: float | None) -> str:
    return "n/a" if value is None else f"{value:+.3f}"


def format_report(report: dict[str, Any]) -> str:
    """A readable table of the report."""
    t = report["trials"]
    a = report["activity"]
    ab = report["area_baseline"]
    s = report["sustained"]
    loc = report["localisation"]
    lat = report["latency_ms"]
    sp = report["speed"]
    rows = [
        ("trials", f"{t['n']}  (tp {t['tp']}, fp {t['fp']}, fn {t['fn']}, tn {t['tn']})"),
        ("precision / recall / F1", f"{_fmt(t['precision'])} / {_fmt(t['recall'])} / {_fmt(t['f1'])}"),
    ]
    for label, entry in sorted(t["by_label"].items()):
        key = "detected" if "detected" in entry else "fired"
        rows.append((f"  {label}", f"{entry[key]} of {entry['n']} {key}"))
    rows += [
        ("kind accuracy", _fmt(t["kind_accuracy"])),
        ("single-event rate", _fmt(t["single_event_rate"])
         + (f" (one-contact trials: {_fmt(t['single_event_rate_one_contact'])}; {t['multi_contact_detected']} detected "
            "trials have several contacts: see contacts)" if t.get("multi_contact_detected") else "")),
        ("activity (hand present)", f"{a['registered']} of {a['hand_present']}"),
        ("activity (empty scenes)", f"{a['empty_fired']} of {a['empty']}"),
        ("area-only baseline", f"threshold {_fmt(ab['threshold'], 0)} px: precision {_fmt(ab['precision'])}, recall {_fmt(ab['recall'])}"),
        ("sustained anchoring AUC", _fmt(s["auc"])),
        ("  fitted threshold", _fmt(s["threshold"])),
        ("  hold-out balanced acc.", _fmt(s["balanced_accuracy_holdout"])),
        ("localisation n", str(loc["n"])),
    ]
    if loc["spread_px"]:
        sp_ = loc["spread_px"]
        rows.append(("  spread px (med/min/max)", f"{sp_['median']:.1f} / {sp_['min']:.1f} / {sp_['max']:.1f}"))
    else:
        rows.append(("  spread px", "n/a"))
    if loc["error_px"]:
        rows.append(("  error px (median/p95)", f"{loc['error_px']['median']:.2f} / {loc['error_px']['p95']:.2f}"))
    else:
        rows.append(("  error px", "n/a"))
    rows.append(("latency ms (median/p95)", f"{lat['median']:.0f} / {lat['p95']:.0f}" if lat else "n/a"))
    if sp["ms_per_frame"]:
        rows.append(
            (
                f"speed at {sp['width']}x{sp['height']}",
                f"{sp['ms_per_frame']['median']:.3f} ms median, {sp['ms_per_frame']['p95']:.3f} ms p95, {sp['fps']:.0f} fps",
            )
        )
    rows += _margin_rows(report.get("margins"))
    rows += _zone_rows(report.get("zones"))
    rows += _contact_rows(report.get("contacts"))
    rows += light_rows(report.get("light"), report.get("switch_recovery"))
    cfg = report.get("touch_config")
    if cfg:
        rows.append(
            (
                "gates used" + (" (fitted on clips)" if cfg["fitted_on_clips"] else ""),
                f"contact_edge {cfg['contact_edge']:.4f}, instant_depth {cfg['instant_depth']:.3f}, "
                f"anchor_threshold {cfg['anchor_threshold']:.3f}"
                + (f", contact_projected_depth {cfg['contact_projected_depth']:.3f}" if "contact_projected_depth" in cfg else ""),
            )
        )
    width = max(len(r[0]) for r in rows)
    return "\n".join(f"{name.ljust(width)}  {value}" for name, value in rows)
