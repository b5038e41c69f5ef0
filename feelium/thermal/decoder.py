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

import dataclasses
import math
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


def _s16(word: int) -> int:
    word = int(word)
    return word - 0x10000 if word >= 0x8000 else word


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
    """``words`` as an (834,) uint16 array, or :class:`FrameRejected` naming what is wrong."""
    w = np.asarray(words)
    if w.shape != (reg.RAW_FRAME_WORDS,):
        raise FrameRejected("shape", f"a raw frame is {reg.RAW_FRAME_WORDS} words, got shape {w.shape}")
    if w.dtype == np.uint16:
        return w
    if w.dtype.kind not in "iu":
        raise FrameRejected("dtype", f"raw words must be integers, got {w.dtype}")
    if w.min() < 0 or w.max() > 0xFFFF:
        raise FrameRejected("range", "raw words must be 16-bit unsigned")
    return w.astype(np.uint16)


def supply_voltage(cal: Calibration, words: np.ndarray) -> float:
    """Vdd in volts from the RAM's supply word, corrected for the ADC resolution in use."""
    control = int(words[reg.RAW_CONTROL])
    resolution_ram = (control & reg.CONTROL_RESOLUTION_MASK) >> reg.CONTROL_RESOLUTION_SHIFT
    correction = 2.0**cal.resolutionEE / 2.0**resolution_ram
    return (correction * _s16(words[reg.VDD_PIX]) - cal.vdd25) / cal.kVdd + 3.3


def ambient_temperature(cal: Calibration, words: np.ndarray, vdd: float) -> float:
    """Ta, the sensor's own temperature in degC, from the PTAT and VBE words (NaN when undefined)."""
    ptat = _s16(words[reg.TA_PTAT])
    vbe = _s16(words[reg.TA_VBE])
    try:
        ptat_art = ptat / (ptat * cal.alphaPTAT + vbe) * 2.0**18
        return (ptat_art / (1.0 + cal.KvPTAT * (vdd - 3.3)) - cal.vPTAT25) / cal.KtPTAT + 25.0
    except ZeroDivisionError:
        return math.nan


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


@dataclass(frozen=True)
class _Plan:
    """What one (mode, sub-page) needs from the calibration, sliced once to the refreshed pixels."""

    mask: np.ndarray
    idx: np.ndarray
    offset: np.ndarray
    kta: np.ndarray
    kv: np.ndarray
    alpha: np.ndarray  # TGC-compensated, before the Ta correction
    interleave_correction: np.ndarray | None  # added when the mode is not the one calibrated


class Decoder:
    """Decodes raw frames of one device (see :func:`object_temperatures`), slicing the calibration once.

    ``reflected_offset_c``: the reflected (surroundings) temperature as an
    offset from Ta; Melexis recommends Ta - 8 when nothing better is known.
    """

    def __init__(self, cal: Calibration, emissivity: float = 1.0, reflected_offset_c: float = -8.0) -> None:
        if not 0.0 < emissivity <= 1.0:
            raise ValueError(f"emissivity must be in (0, 1], got {emissivity!r}")
        self.cal = cal
        self.emissivity = float(emissivity)
        self.reflected_offset_c = float(reflected_offset_c)
        self._aux_used = reg.AUX + np.array(reg.AUX_USED)
        ks_to, ct = cal.ksTo, cal.ct
        self._ks_to = np.asarray(ks_to, dtype=np.float64)
        self._ct = np.asarray(ct, dtype=np.float64)
        self._corr = np.array(
            [
                1.0 / (1.0 + ks_to[0] * 40.0),
                1.0,
                1.0 + ks_to[2] * ct[2],
                (1.0 + ks_to[2] * ct[2]) * (1.0 + ks_to[3] * (ct[3] - ct[2])),
            ]
        )
        self._plans: dict[tuple[str, int], _Plan] = {}

    def _plan(self, mode: reg.Mode, subpage: int) -> _Plan:
        key = (mode, subpage)
        plan = self._plans.get(key)
        if plan is None:
            cal = self.cal
            mask = subpage_mask(mode, subpage)
            idx = np.flatnonzero(mask)
            correction = None
            if (0x80 if mode == "chess" else 0) != cal.calibrationModeEE:
                correction = cal.ilChessC[2] * (2 * IL_PATTERN[idx] - 1) - cal.ilChessC[1] * CONVERSION_PATTERN[idx]
            plan = _Plan(
                mask=mask,
                idx=idx,
                offset=cal.offset[idx],
                kta=cal.kta[idx],
                kv=cal.kv[idx],
                alpha=cal.alpha[idx] - cal.tgc * cal.cpAlpha[subpage],
                interleave_correction=correction,
            )
            self._plans[key] = plan
        return plan

    def decode(self, words: np.ndarray) -> SubpageTemperatures:
        """Decode one raw frame (834 words) into the temperatures of its sub-page's pixels."""
        cal = self.cal
        w = raw_frame_check(words)
        subpage = int(w[reg.RAW_STATUS]) & 1
        control = int(w[reg.RAW_CONTROL])
        mode: reg.Mode = "chess" if control & reg.CONTROL_CHESS else "interleaved"
        plan = self._plan(mode, subpage)
        pixels = w[plan.idx]
        if (pixels == reg.INVALID_WORD).any():
            raise FrameRejected("invalid_word", "sub-page pixels hold 0x7FFF (no data): read before the device wrote them")
        if (w[self._aux_used] == reg.INVALID_WORD).any():
            raise FrameRejected("invalid_word", "auxiliary words hold 0x7FFF (no data)")

        failed = SubpageTemperatures(subpage, mode, math.nan, math.nan, np.full(reg.PIXELS, np.nan), plan.mask, len(plan.idx))
        vdd = supply_voltage(cal, w)
        ta = ambient_temperature(cal, w, vdd)
        if not math.isfinite(ta) or abs(ta) > 1e3:
            return dataclasses.replace(failed, vdd=vdd, ta=ta)
        gain_word = _s16(w[reg.GAIN])
        if gain_word == 0:
            return dataclasses.replace(failed, vdd=vdd, ta=ta)
        ta4 = (ta + KELVIN) ** 4
        tr4 = (ta + self.reflected_offset_c + KELVIN) ** 4
        ta_tr = tr4 - (tr4 - ta4) / self.emissivity
        gain = cal.gainEE / gain_word
        dta, dvdd = ta - 25.0, vdd - 3.3
        if subpage == 0:
            ir_cp = _s16(w[reg.CP_SUBPAGE0]) * gain - cal.cpOffset[0] * (1.0 + cal.cpKta * dta) * (1.0 + cal.cpKv * dvdd)
        else:
            cp1_offset = cal.cpOffset[1] if plan.interleave_correction is None else cal.cpOffset[1] + cal.ilChessC[0]
            ir_cp = _s16(w[reg.CP_SUBPAGE1]) * gain - cp1_offset * (1.0 + cal.cpKta * dta) * (1.0 + cal.cpKv * dvdd)

        with np.errstate(all="ignore"):
            ir = pixels.view(np.int16) * gain
            ir -= plan.offset * (1.0 + plan.kta * dta) * (1.0 + plan.kv * dvdd)
            if plan.interleave_correction is not None:
                ir += plan.interleave_correction
            ir = ir / self.emissivity - cal.tgc * ir_cp
            alpha = plan.alpha * (1.0 + cal.KsTa * dta)
            ks_to1 = cal.ksTo[1]
            sx = np.sqrt(np.sqrt(alpha**3 * (ir + alpha * ta_tr))) * ks_to1
            first = np.sqrt(np.sqrt(ir / (alpha * (1.0 - ks_to1 * KELVIN) + sx) + ta_tr)) - KELVIN
            rng = np.searchsorted(self._ct[1:], first, side="right")  # 0 below ct1, 1 below ct2, 2 below ct3, else 3
            rng[np.isnan(first)] = 1
            ks_to, ct = self._ks_to[rng], self._ct[rng]
            to = np.sqrt(np.sqrt(ir / (alpha * self._corr[rng] * (1.0 + ks_to * (first - ct))) + ta_tr)) - KELVIN
            bad = ~np.isfinite(to)
        if bad.any():
            to[bad] = np.nan
        celsius = np.full(reg.PIXELS, np.nan)
        celsius[plan.idx] = to
        return SubpageTemperatures(subpage, mode, float(vdd), float(ta), celsius, plan.mask, int(bad.sum()))


def object_temperatures(
    cal: Calibration, words: np.ndarray, *, emissivity: float = 1.0, reflected_offset_c: float = -8.0
) -> SubpageTemperatures:
    """Decode one raw frame (834 words) into the temperatures of its sub-page's pixels (one-off use)."""
    return Decoder(cal, emissivity, reflected_offset_c).decode(words)


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
    _decoder: Decoder = field(init=False)
    _image: np.ndarray = field(default_factory=lambda: np.full(reg.PIXELS, np.nan))
    _seen: set[int] = field(default_factory=set)
    last: SubpageTemperatures | None = None

    def __post_init__(self) -> None:
        self._decoder = Decoder(self.cal, self.emissivity, self.reflected_offset_c)

    @property
    def complete(self) -> bool:
        """Whether both sub-pages have been decoded at least once."""
        return self._seen == {0, 1}

    def add(self, words: np.ndarray) -> np.ndarray | None:
        """Decode one raw frame; the updated (24, 32) float32 image, or ``None`` if rejected (counted)."""
        try:
            sub = self._decoder.decode(words)
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
    "Decoder",
    "FrameAssembler",
    "FrameRejected",
    "SubpageTemperatures",
    "ambient_temperature",
    "object_temperatures",
    "raw_frame_check",
    "subpage_mask",
    "supply_voltage",
]
