"""Calibration parameters of one MLX90640, extracted once from its EEPROM (datasheet section 11.1).

The EEPROM packs every per-device constant into bit fields of 832 words; the
decoder needs them as plain numbers and per-pixel arrays. Extraction refuses
a dump that cannot be a real device's (a bus that read all ones or all zeros,
impossible constants, too many or adjacent deviating pixels) with a
:class:`CalibrationError` naming what is wrong, because decoding with garbage
constants yields plausible-looking garbage temperatures.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from feelium.thermal.registers import COLS, EEPROM_WORDS, PIXELS, ROWS

MAX_DEVIATING_PIXELS = 4


class CalibrationError(ValueError):
    """The EEPROM dump cannot be turned into valid calibration parameters."""


def _signed(value: int | np.ndarray, bits: int) -> Any:
    """Two's complement of a ``bits``-wide field."""
    half = 1 << (bits - 1)
    if isinstance(value, np.ndarray):
        value = value.astype(np.int64)
        return np.where(value >= half, value - (1 << bits), value)
    value = int(value)
    return value - (1 << bits) if value >= half else value


def _nibbles(words: np.ndarray) -> np.ndarray:
    """Four signed 4-bit fields per word, lowest nibble first."""
    w = words.astype(np.int64)
    out = np.stack([(w >> s) & 0xF for s in (0, 4, 8, 12)], axis=1).reshape(-1)
    return _signed(out, 4)


@dataclass(frozen=True)
class Calibration:
    """Everything the temperature equations need, as numbers (per-pixel arrays are (768,))."""

    kVdd: int
    vdd25: int
    KvPTAT: float
    KtPTAT: float
    vPTAT25: int
    alphaPTAT: float
    gainEE: int
    tgc: float
    KsTa: float
    resolutionEE: int
    calibrationModeEE: int
    ksTo: tuple[float, float, float, float]
    ct: tuple[int, int, int, int]
    cpAlpha: tuple[float, float]
    cpOffset: tuple[int, int]
    cpKta: float
    cpKv: float
    ilChessC: tuple[float, float, float]
    alpha: np.ndarray  # (768,) float64, 1/(counts per W) sensitivity
    offset: np.ndarray  # (768,) float64
    kta: np.ndarray  # (768,) float64
    kv: np.ndarray  # (768,) float64
    broken_pixels: tuple[int, ...]
    outlier_pixels: tuple[int, ...]

    def summary(self) -> dict[str, Any]:
        """The scalar parameters and the first pixel's, as JSON-ready values."""
        return {
            "kVdd": self.kVdd,
            "vdd25": self.vdd25,
            "KvPTAT": self.KvPTAT,
            "KtPTAT": self.KtPTAT,
            "vPTAT25": self.vPTAT25,
            "alphaPTAT": self.alphaPTAT,
            "gainEE": self.gainEE,
            "tgc": self.tgc,
            "KsTa": self.KsTa,
            "resolutionEE": self.resolutionEE,
            "calibrationModeEE": self.calibrationModeEE,
            "ksTo": list(self.ksTo),
            "ct": list(self.ct),
            "cpAlpha": list(self.cpAlpha),
            "cpOffset": list(self.cpOffset),
            "cpKta": self.cpKta,
            "cpKv": self.cpKv,
            "ilChessC": list(self.ilChessC),
            "alpha_0": float(self.alpha[0]),
            "offset_0_3": [float(v) for v in self.offset[:4]],
            "kta_0": float(self.kta[0]),
            "kv_0": float(self.kv[0]),
            "broken_pixels": list(self.broken_pixels),
            "outlier_pixels": list(self.outlier_pixels),
        }


def _split_index() -> np.ndarray:
    """Per pixel, which of the four row/column parity constants applies (0-based even/odd)."""
    rows, cols = np.divmod(np.arange(PIXELS), COLS)
    return 2 * (rows % 2) + (cols % 2)


def _check_dump(ee: np.ndarray) -> None:
    if ee.shape != (EEPROM_WORDS,):
        raise CalibrationError(f"EEPROM dump must be {EEPROM_WORDS} words, got shape {ee.shape}")
    if np.all(ee == 0xFFFF):
        raise CalibrationError("EEPROM dump is all 0xFFFF: the bus read nothing (sensor absent or SDA stuck high)")
    if np.all(ee == 0):
        raise CalibrationError("EEPROM dump is all zero: the bus read nothing (SDA stuck low or wrong device)")


def _deviating_pixels(pixel_words: np.ndarray) -> tuple[tuple[int, ...], tuple[int, ...]]:
    broken = tuple(int(p) for p in np.flatnonzero(pixel_words == 0))
    outliers = tuple(int(p) for p in np.flatnonzero((pixel_words & 1) != 0) if p not in broken)
    deviating = sorted(broken + outliers)
    if len(deviating) > MAX_DEVIATING_PIXELS:
        raise CalibrationError(
            f"{len(deviating)} deviating pixels ({len(broken)} broken, {len(outliers)} outliers): "
            f"more than the {MAX_DEVIATING_PIXELS} a device may have"
        )
    for i, a in enumerate(deviating):
        for b in deviating[i + 1 :]:
            (ra, ca), (rb, cb) = divmod(a, COLS), divmod(b, COLS)
            if abs(ra - rb) <= 1 and abs(ca - cb) <= 1:
                raise CalibrationError(f"deviating pixels {a} and {b} are adjacent: their neighbours cannot stand in")
    return broken, outliers


def extract_calibration(eeprom: np.ndarray | list[int]) -> Calibration:
    """Parse and sanity-check an EEPROM dump (832 words from 0x2400)."""
    ee = np.asarray(eeprom)
    if ee.dtype.kind not in "iu":
        raise CalibrationError(f"EEPROM words must be integers, got dtype {ee.dtype}")
    if ee.size and (ee.min() < 0 or ee.max() > 0xFFFF):
        raise CalibrationError("EEPROM words must be 16-bit unsigned")
    ee = ee.astype(np.int64)
    _check_dump(ee)
    e = [int(v) for v in ee[:64]]

    kVdd = _signed((e[51] & 0xFF00) >> 8, 8) * 32
    vdd25 = (((e[51] & 0x00FF) - 256) << 5) - 8192
    KvPTAT = _signed((e[50] & 0xFC00) >> 10, 6) / 4096.0
    KtPTAT = _signed(e[50] & 0x03FF, 10) / 8.0
    vPTAT25 = _signed(e[49], 16)
    alphaPTAT = ((e[16] & 0xF000) >> 12) / 4.0 + 8.0
    gainEE = _signed(e[48], 16)
    tgc = _signed(e[60] & 0x00FF, 8) / 32.0
    KsTa = _signed((e[60] & 0xFF00) >> 8, 8) / 8192.0
    resolutionEE = (e[56] & 0x3000) >> 12
    calibrationModeEE = ((e[10] & 0x0800) >> 4) ^ 0x80

    step = ((e[63] & 0x3000) >> 12) * 10
    ct2 = ((e[63] & 0x00F0) >> 4) * step
    ct3 = ct2 + ((e[63] & 0x0F00) >> 8) * step
    ct = (-40, 0, ct2, ct3)
    ks_to_scale = float(1 << ((e[63] & 0x000F) + 8))
    ksTo = (
        _signed(e[61] & 0x00FF, 8) / ks_to_scale,
        _signed((e[61] & 0xFF00) >> 8, 8) / ks_to_scale,
        _signed(e[62] & 0x00FF, 8) / ks_to_scale,
        _signed((e[62] & 0xFF00) >> 8, 8) / ks_to_scale,
    )

    # compensation pixels
    cp_alpha_scale = ((e[32] & 0xF000) >> 12) + 27
    cp_offset0 = _signed(e[58] & 0x03FF, 10)
    cpOffset = (cp_offset0, cp_offset0 + _signed((e[58] & 0xFC00) >> 10, 6))
    cp_alpha0 = _signed(e[57] & 0x03FF, 10) / 2.0**cp_alpha_scale
    cpAlpha = (cp_alpha0, (1.0 + _signed((e[57] & 0xFC00) >> 10, 6) / 128.0) * cp_alpha0)
    kta_scale1 = ((e[56] & 0x00F0) >> 4) + 8
    kta_scale2 = e[56] & 0x000F
    kv_scale = (e[56] & 0x0F00) >> 8
    cpKta = _signed(e[59] & 0x00FF, 8) / 2.0**kta_scale1
    cpKv = _signed((e[59] & 0xFF00) >> 8, 8) / 2.0**kv_scale

    ilChessC = (
        _signed(e[53] & 0x003F, 6) / 16.0,
        _signed((e[53] & 0x07C0) >> 6, 5) / 2.0,
        _signed((e[53] & 0xF800) >> 11, 5) / 8.0,
    )

    pixel_words = ee[64:]
    rows, cols = np.divmod(np.arange(PIXELS), COLS)
    split = _split_index()

    # offsets
    occ_rem_scale = e[16] & 0x000F
    occ_col_scale = (e[16] & 0x00F0) >> 4
    occ_row_scale = (e[16] & 0x0F00) >> 8
    offset_ref = _signed(e[17], 16)
    occ_row = _nibbles(ee[18:24])
    occ_col = _nibbles(ee[24:32])
    offset = (
        offset_ref
        + (occ_row[rows] << occ_row_scale)
        + (occ_col[cols] << occ_col_scale)
        + _signed((pixel_words & 0xFC00) >> 10, 6) * (1 << occ_rem_scale)
    ).astype(np.float64)

    # sensitivities
    acc_rem_scale = e[32] & 0x000F
    acc_col_scale = (e[32] & 0x00F0) >> 4
    acc_row_scale = (e[32] & 0x0F00) >> 8
    alpha_scale = ((e[32] & 0xF000) >> 12) + 30
    alpha_ref = e[33]
    acc_row = _nibbles(ee[34:40])
    acc_col = _nibbles(ee[40:48])
    alpha = (
        alpha_ref
        + (acc_row[rows] << acc_row_scale)
        + (acc_col[cols] << acc_col_scale)
        + _signed((pixel_words & 0x03F0) >> 4, 6) * (1 << acc_rem_scale)
    ) / 2.0**alpha_scale

    # Kta: row/column parity constant plus the pixel's own 3-bit part
    kta_rc = np.array(
        [_signed((e[54] & 0xFF00) >> 8, 8), _signed((e[55] & 0xFF00) >> 8, 8), _signed(e[54] & 0x00FF, 8), _signed(e[55] & 0x00FF, 8)]
    )
    kta = (kta_rc[split] + _signed((pixel_words & 0x000E) >> 1, 3) * (1 << kta_scale2)) / 2.0**kta_scale1

    # Kv: one constant per row/column parity
    kv_t = np.array(
        [_signed((e[52] & 0xF000) >> 12, 4), _signed((e[52] & 0x00F0) >> 4, 4), _signed((e[52] & 0x0F00) >> 8, 4), _signed(e[52] & 0x000F, 4)]
    )
    kv = kv_t[split] / 2.0**kv_scale

    broken, outliers = _deviating_pixels(pixel_words)

    problems = []
    if kVdd == 0:
        problems.append("kVdd is 0 (Vdd cannot be computed)")
    if KtPTAT == 0:
        problems.append("KtPTAT is 0 (Ta cannot be computed)")
    if vPTAT25 <= 0:
        problems.append(f"vPTAT25 is {vPTAT25} (must be positive)")
    if gainEE == 0:
        problems.append("gainEE is 0")
    if not ct[1] < ct[2] < ct[3]:
        problems.append(f"temperature range corners {ct} are not increasing")
    good = np.ones(PIXELS, dtype=bool)
    good[list(broken + outliers)] = False
    if not np.all(alpha[good] > 0):
        problems.append(f"{int(np.sum(alpha[good] <= 0))} pixels have a non-positive sensitivity")
    if cpAlpha[0] <= 0 or cpAlpha[1] <= 0:
        problems.append(f"compensation pixel sensitivities {cpAlpha} are not positive")
    if problems:
        raise CalibrationError("impossible calibration: " + "; ".join(problems))

    return Calibration(
        kVdd=kVdd,
        vdd25=vdd25,
        KvPTAT=KvPTAT,
        KtPTAT=KtPTAT,
        vPTAT25=vPTAT25,
        alphaPTAT=alphaPTAT,
        gainEE=gainEE,
        tgc=tgc,
        KsTa=KsTa,
        resolutionEE=resolutionEE,
        calibrationModeEE=calibrationModeEE,
        ksTo=ksTo,
        ct=ct,
        cpAlpha=cpAlpha,
        cpOffset=cpOffset,
        cpKta=cpKta,
        cpKv=cpKv,
        ilChessC=ilChessC,
        alpha=alpha.astype(np.float64),
        offset=offset,
        kta=kta.astype(np.float64),
        kv=kv.astype(np.float64),
        broken_pixels=broken,
        outlier_pixels=outliers,
    )


__all__ = ["Calibration", "CalibrationError", "MAX_DEVIATING_PIXELS", "ROWS", "extract_calibration"]
