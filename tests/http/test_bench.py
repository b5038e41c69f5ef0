"""``feelium bench link`` (alias ``bench http``) runs at a tiny size and reports every measurement (numbers are not judged here)."""

from __future__ import annotations

import argparse
import json

import pytest

from feelium.lab.http.bench import bench_http_command


@pytest.mark.slow
def test_bench_http_runs_small_and_reports_every_key(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "http.json"
    args = argparse.Namespace(requests=10, seconds=0.3, fps=30.0, speech_seconds=0.5, no_abuse=True, json=str(out))  # abuse: test_live_abuse
    assert bench_http_command(args) == 0
    result = json.loads(out.read_text())

    motion = result["motion_round_trip"]
    for key in ("baseline_health", "motion", "sent_to_hub"):
        assert motion[key]["n"] == 10 and motion[key]["median_ms"] > 0 and motion[key]["p95_ms"] >= motion[key]["median_ms"]
    events = result["touch_event_latency"]
    for kind in ("baseline_bus", "long_poll", "sse", "websocket"):
        assert events[kind]["n"] == 10, kind  # every published touch reached every transport
    video = result["mjpeg_4_clients_1_stalled"]
    assert len(video["baseline_3_readers"]["readers"]) == 3
    assert len(video["3_readers_plus_1_stalled"]["readers"]) == 3
    assert all(r["fps"] > 0 for r in video["3_readers_plus_1_stalled"]["readers"])
    assert video["stalled_dropped"] is True
    for run in ("no_inflight_limit", "inflight_limit"):
        assert video["slow_reader"][run]["fps"] > 0 and video["slow_reader"][run]["age_median_ms"] > 0
    assert "slow_reader_age_ratio" in video
    assert "ratio_fps_with_stalled_vs_baseline" in video
    speech = result["speech_stream_vs_long_poll"]
    for kind in ("bus", "long_poll", "stream"):
        assert speech[kind]["chunks"] == speech["chunks_published"], kind  # every chunk reached every reader
        assert speech[kind]["delay_median_ms"] >= 0 and speech[kind]["gap_p50_ms"] > 0
    assert speech["long_poll"]["requests_per_s"] > 0 and "ratio_delay_median_stream_vs_long_poll" in speech
    flood = result["stop_under_flood"]
    for key in ("quiet", "bystander_during_flood", "flooder_own_stop"):
        assert flood[key]["refused"] == 0 and flood[key]["n"] == 10, key  # stop always wins, also under a flood
    assert flood["flood_statuses"].get("429", 0) > 0  # the flood really was over the shipped limit
    table = capsys.readouterr().out
    assert "POST /motion round trip" in table and "3 readers + 1 stalled" in table and "slow reader" in table
    assert "GET /speech/stream WebSocket" in table and "`stop` from a bystander, during a flood" in table
    assert "rss_under_abuse" not in result


def test_bench_http_rejects_a_meaningless_size(capsys) -> None:  # type: ignore[no-untyped-def]
    assert bench_http_command(argparse.Namespace(requests=3, seconds=1.0, fps=30.0, json=None)) == 2
    assert "--requests" in capsys.readouterr().err
