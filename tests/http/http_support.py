"""Constants and fakes shared by the headset-link tests."""

from __future__ import annotations

TOKEN = "test-token-0123456789abcdef"
AUTH = {"Authorization": f"Bearer {TOKEN}"}


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


class FakeScene:
    """Stands in for the simulator's live rear scene."""

    width = 640
    height = 480

    def __init__(self) -> None:
        self.calls: list[tuple] = []

    def press(self, x: float, y: float, t: float, hover: bool = False) -> None:
        if hover and x < 1:
            raise ValueError("cannot hover at the edge")
        self.calls.append(("press", x, y, t, hover))

    def release(self, t: float) -> None:
        self.calls.append(("release", t))
