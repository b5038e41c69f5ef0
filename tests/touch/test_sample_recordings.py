"""The committed sample recordings replayed end to end: the events that come out, against their labels."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from feelium.cli import main
from feelium.recording import Recording

SAMPLES = Path(__file__).resolve().parents[2] / "recordings"


def replay(name: str, capsys: pytest.CaptureFixture[str]) -> list[dict]:
    assert main(["replay", str(SAMPLES / name)]) == 0
    return [json.loads(line) for line in capsys.readouterr().out.splitlines() if line.startswith("{")]


def test_the_tap_sample_gives_one_tap_where_and_when_the_finger_touched(capsys) -> None:  # type: ignore[no-untyped-def]
    contact = Recording(SAMPLES / "tap").labels.contacts[0]  # type: ignore[union-attr]
    events = replay("tap", capsys)
    assert [e["phase"] for e in events if e["phase"] != "move"] == ["down", "up"]
    assert {e["id"] for e in events} == {1} and events[-1]["kind"] == "tap"
    down = events[0]
    assert contact.t_on <= down["t"] <= contact.t_off + 0.2  # confirmed within the contact or just after
    x, y = contact.path[0][1], contact.path[0][2]
    assert math.hypot(down["x"] - x, down["y"] - y) < 3.0  # the paper protocol's localisation, about 1 px here


def test_the_hover_sample_gives_no_touch(capsys) -> None:  # type: ignore[no-untyped-def]
    assert Recording(SAMPLES / "hover").labels.contacts == ()  # type: ignore[union-attr]
    assert replay("hover", capsys) == []


def test_the_samples_are_scored_by_eval(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    report = tmp_path / "report.json"
    assert main(["eval", str(SAMPLES), "--json", str(report)]) == 0
    scored = json.loads(report.read_text())
    assert (scored["trials"]["tp"], scored["trials"]["fp"], scored["trials"]["fn"], scored["trials"]["tn"]) == (1, 0, 0, 1)
    assert scored["trials"]["kind_accuracy"] == 1.0
