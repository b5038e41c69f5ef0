"""Shared fixtures: the Melexis example (tests/data/mlx90640, source named in its README)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from feelium.thermal.calibration import Calibration, extract_calibration

VENDOR_JSON = Path(__file__).resolve().parents[1] / "data" / "mlx90640" / "melexis-example.json"


def _words(hex_words: list[str]) -> np.ndarray:
    return np.array([int(w, 16) for w in hex_words], dtype=np.int64)


def vendor_raw_frame(vendor: dict, k: int) -> np.ndarray:
    """Frame k in the recording layout: the vendor puts control then sub-page; we store status then control."""
    f = _words(vendor[f"frame_{k}"])
    status = 0x0008 | int(f[833])  # new data, measured sub-page
    return np.concatenate([f[:832], [status, f[832]]]).astype(np.uint16)


@pytest.fixture(scope="session")
def vendor() -> dict:
    return json.loads(VENDOR_JSON.read_text())


@pytest.fixture(scope="session")
def vendor_eeprom_words(vendor) -> np.ndarray:
    return _words(vendor["eeprom_0x2400"]).astype(np.uint16)


@pytest.fixture(scope="session")
def cal(vendor_eeprom_words) -> Calibration:
    return extract_calibration(vendor_eeprom_words)


@pytest.fixture(scope="session")
def vendor_frames(vendor) -> list[np.ndarray]:
    return [vendor_raw_frame(vendor, 0), vendor_raw_frame(vendor, 1)]
