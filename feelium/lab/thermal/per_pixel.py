"""The same temperature equations, one pixel at a time in plain Python.

This is how the common pure-Python MLX90640 drivers compute a frame. It is
kept as the baseline `feelium bench thermal` measures the vectorised decoder
against, and as an independent second reading of the datasheet that the
property tests compare the decoder with. Not used on the live path.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from feelium.thermal.calibration import Calibration

KELVIN = 273.15


def _s16(word: int) -> int:
    return word - 0x10000 if word >= 0x8000 else word


def per_pixel_temperatures(
    cal: Calibration, words: Sequence[int], emissivity: float = 1.0, reflected_offset_c: float = -8.0
) -> list[float]:
    """768 temperatures (NaN for pixels the frame's sub-page did not refresh or whose equations fail)."""
    words = [int(w) for w in words]
    alpha_px, offset_px = cal.alpha.tolist(), cal.offset.tolist()
    kta_px, kv_px = cal.kta.tolist(), cal.kv.tolist()
    subpage = words[832] & 1
    control = words[833]
    chess_mode = 0x80 if control & 0x1000 else 0

    resolution_ram = (control & 0x0C00) >> 10
    vdd = (2**cal.resolutionEE / 2**resolution_ram * _s16(words[810]) - cal.vdd25) / cal.kVdd + 3.3
    ptat = _s16(words[800])
    vbe = _s16(words[768])
    try:
        ptat_art = ptat / (ptat * cal.alphaPTAT + vbe) * 2**18
    except ZeroDivisionError:
        return [math.nan] * 768
    ta = (ptat_art / (1 + cal.KvPTAT * (vdd - 3.3)) - cal.vPTAT25) / cal.KtPTAT + 25
    ta4 = (ta + KELVIN) ** 4
    tr4 = (ta + reflected_offset_c + KELVIN) ** 4
    ta_tr = tr4 - (tr4 - ta4) / emissivity

    gain_word = _s16(words[778])
    if gain_word == 0:
        return [math.nan] * 768
    gain = cal.gainEE / gain_word
    cp_scale = (1 + cal.cpKta * (ta - 25)) * (1 + cal.cpKv * (vdd - 3.3))
    ir_cp = [_s16(words[776]) * gain - cal.cpOffset[0] * cp_scale, 0.0]
    if chess_mode == cal.calibrationModeEE:
        ir_cp[1] = _s16(words[808]) * gain - cal.cpOffset[1] * cp_scale
    else:
        ir_cp[1] = _s16(words[808]) * gain - (cal.cpOffset[1] + cal.ilChessC[0]) * cp_scale

    ks_to, ct = cal.ksTo, cal.ct
    corr = [
        1 / (1 + ks_to[0] * 40),
        1.0,
        1 + ks_to[2] * ct[2],
        (1 + ks_to[2] * ct[2]) * (1 + ks_to[3] * (ct[3] - ct[2])),
    ]

    out = [math.nan] * 768
    for p in range(768):
        il_pattern = (p // 32) % 2
        chess_pattern = il_pattern ^ (p % 2)
        pattern = chess_pattern if chess_mode else il_pattern
        if pattern != subpage:
            continue
        ir = _s16(words[p]) * gain
        ir -= offset_px[p] * (1 + kta_px[p] * (ta - 25)) * (1 + kv_px[p] * (vdd - 3.3))
        if chess_mode != cal.calibrationModeEE:
            conversion = ((p + 2) // 4 - (p + 3) // 4 + (p + 1) // 4 - p // 4) * (1 - 2 * il_pattern)
            ir += cal.ilChessC[2] * (2 * il_pattern - 1) - cal.ilChessC[1] * conversion
        ir = ir / emissivity - cal.tgc * ir_cp[subpage]
        alpha = (alpha_px[p] - cal.tgc * cal.cpAlpha[subpage]) * (1 + cal.KsTa * (ta - 25))
        try:
            sx = math.sqrt(math.sqrt(alpha**3 * (ir + alpha * ta_tr))) * ks_to[1]
            first = math.sqrt(math.sqrt(ir / (alpha * (1 - ks_to[1] * KELVIN) + sx) + ta_tr)) - KELVIN
            if first < ct[1]:
                r = 0
            elif first < ct[2]:
                r = 1
            elif first < ct[3]:
                r = 2
            else:
                r = 3
            out[p] = math.sqrt(math.sqrt(ir / (alpha * corr[r] * (1 + ks_to[r] * (first - ct[r]))) + ta_tr)) - KELVIN
        except (ValueError, ZeroDivisionError, OverflowError):
            out[p] = math.nan
    return out


__all__ = ["per_pixel_temperatures"]
