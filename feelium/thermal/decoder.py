"""Raw MLX90640 words to object temperatures, vectorised over the pixels (datasheet section 11.2).

One raw frame is what the driver reads after the device signals a new
sub-page: 832 RAM words (0x0400..0x073F), then the status register (its bit 0
is the sub-page just measured), then the control register (its bit 12 says
chess or interleaved). Each sub-page refreshes half the pixels, so
:class:`FrameAssembler` keeps the image and overwrites the half that is new.

Numbers never escape as exceptions: a frame with the device's "no data" word
0x7FFF is rejected as a whole (:class:`FrameRejected`), while a pixel whose
equations fail (negative radicand, zero gain, extreme Ta) becomes NaN and is
counted, and the rest of the frame stands.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from feelium.thermal import registers as reg
from feelium.thermal.calibration import Calibration

KELVIN = 273.15


class FrameRejected(ValueError):
    """A raw frame that must not be decoded; ``reason`` is a short counter name."""

    def __init__(self, reason: str, message: str) -> None:
        super().__init__(message)
        self.reason = reason


def _signed16(words: np.ndarray) -> np.ndarray:
    w = words.astype(np.int64)
    return np.where(w >= 0x8000, w - 0x10000, w).astype(np.float64)


def _patterns() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per pixel: interleaved sub-page (row parity), chess sub-page, and the interleave conversion sign."""
    p = np.arange(reg.PIXELS)
    il = (p // 32) % 2
    chess = il ^ (p % 2)
    conversion = ((p + 2) // 4 - (p + 3) // 4 + (p + 1) // 4 - p // 4) * (1 - 2 * il)
    return il, chess, conversion


IL_PATTERN, CHESS_PATTERN, CONVERSION_PATTERN = _patterns()


def subpage_mask(mode: reg.Mode, subpage: int) -> np.ndarray:
    """Which of the 768 pixels a sub-page refreshes in ``mode``."""
    return (CHESS_PATTERN if mode == "chess" else IL_PATTERN) == subpage


def raw_frame_check(words: np.ndarray) -> np.ndarray:
    """``words`` as an (834,) int64 array, or :class:`FrameRejected` naming what is wrong."""
    w = np.asarray(words)
    if w.shape != (reg.RAW_FRAME_WORDS,):
        raise FrameRejected("shape", f"a raw frame is {reg.RAW_FRAME_WORDS} words, got shape {w.shape}")
    if w.dtype.kind not in "iu":
        raise FrameRejected("dtype", f"raw words must be integers, got {w.dtype}")
    return w.astype(np.int64)


def supply_voltage(cal: Calibration, words: np.ndarray) -> float:
    """Vdd in volts from the RAM's supply word, corrected for the ADC resolution in use."""
    control = int(words[reg.RAW_CONTROL])
    resolution_ram = (control & reg.CONTROL_RESOLUTION_MASK) >> reg.CONTROL_RESOLUTION_SHIFT
    correction = 2.0**cal.resolutionEE / 2.0**resolution_ram
    vdd_raw = float(_signed16(words[reg.VDD_PIX]))
    return (correction * vdd_raw - cal.vdd25) / cal.kVdd + 3.3


def ambient_temperature(cal: Calibration, words: np.ndarray, vdd: float) -> float:
    """Ta, the sensor's own temperature in degC, from the PTAT and VBE words."""
    ptat = float(_signed16(words[reg.TA_PTAT]))
    vbe = float(_signed16(words[reg.TA_VBE]))
    with np.errstate(all="ignore"):
        ptat_art = np.float64(ptat) / (ptat * cal.alphaPTAT + vbe) * 2.0**18
        ta = (ptat_art / (1.0 + cal.KvPTAT * (vdd - 3.3)) - cal.vPTAT25) / cal.KtPTAT + 25.0
    return float(ta)


@dataclass(frozen=True)
class SubpageTemperatures:
    """Object temperatures of one sub-page's pixels (the others are NaN in ``celsius``)."""

    subpage: int
    mode: reg.Mode
    vdd: float
    ta: float
    celsius: np.ndarray  # (768,) float64
    mask: np.ndarray  # (768,) bool: the pixels this sub-page refreshed
    failed_pixels: int  # refreshed pixels whose equations gave no finite value


def object_temperatures(
    cal: Calibration, words: np.ndarray, *, emissivity: float = 1.0, reflected_offset_c: float = -8.0
) -> SubpageTemperatures:
    """Decode one raw frame (834 words) into the temperatures of its sub-page's pixels.

    ``reflected_offset_c``: the reflected (surroundings) temperature as an
    offset from Ta; Melexis recommends Ta - 8 when nothing better is known.
    """
    if not 0.0 < emissivity <= 1.0:
        raise ValueError(f"emissivity must be in (0, 1], got {emissivity!r}")
    w = raw_frame_check(words)
    subpage = int(w[reg.RAW_STATUS]) & 1
    control = int(w[reg.RAW_CONTROL])
    mode: reg.Mode = "chess" if control & reg.CONTROL_CHESS else "interleaved"
    mask = subpage_mask(mode, subpage)
    if np.any(w[: reg.PIXELS][mask] == reg.INVALID_WORD):
        raise FrameRejected("invalid_word", "sub-page pixels hold 0x7FFF (no data): read before the device wrote them")
    if np.any(w[reg.AUX + np.array(reg.AUX_USED)] == reg.INVALID_WORD):
        raise FrameRejected("invalid_word", "auxiliary words hold 0x7FFF (no data)")

    with np.errstate(all="ignore"):
        vdd = supply_voltage(cal, w)
        ta = ambient_temperature(cal, w, vdd)
        ta4 = (ta + KELVIN) ** 4
        tr4 = (ta + reflected_offset_c + KELVIN) ** 4
        ta_tr = tr4 - (tr4 - ta4) / emissivity

        gain = cal.gainEE / _signed16(w[reg.GAIN])
        cal_mode = 0x80 if mode == "chess" else 0
        dta, dvdd = ta - 25.0, vdd - 3.3
        cp_scale = (1.0 + cal.cpKta * dta) * (1.0 + cal.cpKv * dvdd)
        cp0 = _signed16(w[reg.CP_SUBPAGE0]) * gain - cal.cpOffset[0] * cp_scale
        cp1_offset = cal.cpOffset[1] if cal_mode == cal.calibrationModeEE else cal.cpOffset[1] + cal.ilChessC[0]
        cp1 = _signed16(w[reg.CP_SUBPAGE1]) * gain - cp1_offset * cp_scale
        ir_cp = cp0 if subpage == 0 else cp1

        idx = np.flatnonzero(mask)
        ir = _signed16(w[idx]) * gain
        ir -= cal.offset[idx] * (1.0 + cal.kta[idx] * dta) * (1.0 + cal.kv[idx] * dvdd)
        if cal_mode != cal.calibrationModeEE:
            ir += cal.ilChessC[2] * (2 * IL_PATTERN[idx] - 1) - cal.ilChessC[1] * CONVERSION_PATTERN[idx]
        ir = ir / emissivity - cal.tgc * ir_cp
        alpha = (cal.alpha[idx] - cal.tgc * cal.cpAlpha[subpage]) * (1.0 + cal.KsTa * dta)

        ks_to = np.asarray(cal.ksTo)
        ct = np.asarray(cal.ct, dtype=np.float64)
        sx = np.sqrt(np.sqrt(alpha**3 * (ir + alpha * ta_tr))) * ks_to[1]
        first = np.sqrt(np.sqrt(ir / (alpha * (1.0 - ks_to[1] * KELVIN) + sx) + ta_tr)) - KELVIN
        corr = np.array(
            [
                1.0 / (1.0 + ks_to[0] * 40.0),
                1.0,
                1.0 + ks_to[2] * ct[2],
                (1.0 + ks_to[2] * ct[2]) * (1.0 + ks_to[3] * (ct[3] - ct[2])),
            ]
        )
        rng = np.searchsorted(ct[1:], first, side="right")  # 0 below ct1, 1 below ct2, 2 below ct3, else 3
        rng = np.where(np.isfinite(first), rng, 1)
        to = np.sqrt(np.sqrt(ir / (alpha * corr[rng] * (1.0 + ks_to[rng] * (first - ct[rng]))) + ta_tr)) - KELVIN

    to = np.where(np.isfinite(to), to, np.nan)
    celsius = np.full(reg.PIXELS, np.nan)
    celsius[idx] = to
    return SubpageTemperatures(
        subpage=subpage,
        mode=mode,
        vdd=float(vdd),
        ta=float(ta),
        celsius=celsius,
        mask=mask,
        failed_pixels=int(np.sum(~np.isfinite(to))),
    )


def _neighbour_mean(image: np.ndarray, pixel: int) -> float:
    row, col = divmod(pixel, reg.COLS)
    values = [
        image[r, c]
        for r, c in ((row - 1, col), (row + 1, col), (row, col - 1), (row, col + 1))
        if 0 <= r < reg.ROWS and 0 <= c < reg.COLS and np.isfinite(image[r, c])
    ]
    return float(np.mean(values)) if values else float("nan")


@dataclass
class FrameAssembler:
    """Keeps the full 24x32 image, overwrites each new sub-page's half and fills deviating pixels.

    Broken and outlier pixels (from the EEPROM) take the mean of their
    finite 4-neighbours; pixels whose equations failed stay NaN.
    """

    cal: Calibration
    emissivity: float = 1.0
    reflected_offset_c: float = -8.0
    decoded: int = 0
    rejected: dict[str, int] = field(default_factory=dict)
    failed_pixels: int = 0
    _image: np.ndarray = field(default_factory=lambda: np.full(reg.PIXELS, np.nan))
    _seen: set[int] = field(default_factory=set)
    last: SubpageTemperatures | None = None

    @property
    def complete(self) -> bool:
        """Whether both sub-pages have been decoded at least once."""
        return self._seen == {0, 1}

    def add(self, words: np.ndarray) -> np.ndarray | None:
        """Decode one raw frame; the updated (24, 32) float32 image, or ``None`` if rejected (counted)."""
        try:
            sub = object_temperatures(
                self.cal, words, emissivity=self.emissivity, reflected_offset_c=self.reflected_offset_c
            )
        except FrameRejected as exc:
            self.rejected[exc.reason] = self.rejected.get(exc.reason, 0) + 1
            return None
        self.decoded += 1
        self.failed_pixels += sub.failed_pixels
        self.last = sub
        self._image[sub.mask] = sub.celsius[sub.mask]
        self._seen.add(sub.subpage)
        return self.image()

    def image(self) -> np.ndarray:
        image = self._image.reshape(reg.ROWS, reg.COLS).copy()
        for pixel in self.cal.broken_pixels + self.cal.outlier_pixels:
            image.flat[pixel] = np.nan
        for pixel in self.cal.broken_pixels + self.cal.outlier_pixels:
            image.flat[pixel] = _neighbour_mean(image, pixel)
        return image.astype(np.float32)


__all__ = [
    "FrameAssembler",
    "FrameRejected",
    "SubpageTemperatures",
    "ambient_temperature",
    "object_temperatures",
    "raw_frame_check",
    "subpage_mask",
    "supply_voltage",
]
