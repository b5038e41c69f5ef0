"""The vectorised decoder: agrees with the per-pixel equations, rejects 0x7FFF frames, never raises on numbers."""

import warnings

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from feelium.thermal import registers as reg
from feelium.thermal.calibration import extract_calibration
from feelium.thermal.decoder import Decoder, FrameAssembler, FrameRejected, object_temperatures, subpage_mask
from feelium.lab.thermal.per_pixel import per_pixel_temperatures


def test_subpage_masks_split_the_sensor_in_two():
    for mode in ("chess", "interleaved"):
        a, b = subpage_mask(mode, 0), subpage_mask(mode, 1)
        assert a.sum() == b.sum() == 384 and not np.any(a & b)
    chess = subpage_mask("chess", 0).reshape(24, 32)
    assert chess[0, 0] and not chess[0, 1] and not chess[1, 0] and chess[1, 1]
    il = subpage_mask("interleaved", 0).reshape(24, 32)
    assert il[0].all() and not il[1].any()


def test_invalid_word_in_subpage_pixels_rejects_the_frame(cal, vendor_frames):
    frame = vendor_frames[0].copy()
    frame[0] = reg.INVALID_WORD  # pixel (0, 0) belongs to chess sub-page 0
    with pytest.raises(FrameRejected) as err:
        object_temperatures(cal, frame)
    assert err.value.reason == "invalid_word"


def test_invalid_word_in_the_other_subpage_is_ignored(cal, vendor_frames):
    frame = vendor_frames[0].copy()
    frame[1] = reg.INVALID_WORD  # pixel (0, 1) belongs to sub-page 1
    sub = object_temperatures(cal, frame)
    assert sub.failed_pixels == 0


def test_invalid_auxiliary_word_rejects_the_frame(cal, vendor_frames):
    frame = vendor_frames[1].copy()
    frame[reg.TA_PTAT] = reg.INVALID_WORD
    with pytest.raises(FrameRejected):
        object_temperatures(cal, frame)


def test_assembler_counts_rejections_and_keeps_the_last_image(cal, vendor_frames):
    asm = FrameAssembler(cal)
    asm.add(vendor_frames[0])
    good = asm.add(vendor_frames[1])
    bad = vendor_frames[0].copy()
    bad[2] = reg.INVALID_WORD
    assert asm.add(bad) is None
    assert asm.add(np.zeros(10, dtype=np.uint16)) is None
    assert asm.rejected == {"invalid_word": 1, "shape": 1}
    assert np.array_equal(asm.image(), good)


def test_broken_pixel_is_filled_from_its_neighbours(vendor_eeprom_words, vendor_frames):
    ee = vendor_eeprom_words.copy()
    ee[64 + 100] = 0  # pixel (3, 4) broken
    cal = extract_calibration(ee)
    asm = FrameAssembler(cal)
    asm.add(vendor_frames[0])
    image = asm.add(vendor_frames[1])
    expected = np.mean([image[2, 4], image[4, 4], image[3, 3], image[3, 5]])
    assert image[3, 4] == pytest.approx(expected, abs=1e-4)
    assert np.isfinite(image).all()


def test_outlier_pixel_is_filled_from_its_neighbours_whatever_it_reads(vendor_eeprom_words, vendor_frames):
    ee = vendor_eeprom_words.copy()
    ee[64 + 500] |= 1  # pixel (15, 20) flagged as an outlier in the EEPROM
    cal = extract_calibration(ee)
    assert cal.outlier_pixels == (500,)
    frames = [f.copy() for f in vendor_frames]
    for f in frames:
        f[500] = 0x7000  # a wild reading on the outlier itself
    asm = FrameAssembler(cal)
    asm.add(frames[0])
    image = asm.add(frames[1])
    expected = np.mean([image[14, 20], image[16, 20], image[15, 19], image[15, 21]])
    assert image[15, 20] == pytest.approx(expected, abs=1e-4)
    assert 20.0 < image[15, 20] < 40.0


def test_emissivity_and_reflected_temperature_change_a_warm_reading(cal, vendor_frames):
    """Below 1, emissivity scales up what a body radiates above its surroundings (To - Tr grows)."""
    frame = vendor_frames[0]
    black = object_temperatures(cal, frame, emissivity=1.0, reflected_offset_c=-8.0)
    grey = object_temperatures(cal, frame, emissivity=0.9, reflected_offset_c=-8.0)
    warm_room = object_temperatures(cal, frame, emissivity=0.9, reflected_offset_c=0.0)
    m = black.mask
    tr = black.ta - 8.0
    assert np.all(black.celsius[m] > tr)  # the vendor scene is warmer than Ta - 8
    assert np.all(grey.celsius[m] > black.celsius[m] + 0.05)
    assert np.all(warm_room.celsius[m] < grey.celsius[m])  # warmer surroundings explain more of the signal
    black_warm_room = object_temperatures(cal, frame, emissivity=1.0, reflected_offset_c=0.0)
    assert np.allclose(black_warm_room.celsius[m], black.celsius[m], atol=1e-9)  # a black body reflects nothing


def test_zero_gain_gives_nan_pixels_not_an_exception(cal, vendor_frames):
    frame = vendor_frames[0].copy()
    frame[reg.GAIN] = 0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sub = object_temperatures(cal, frame)
    assert sub.failed_pixels == 384 and np.isnan(sub.celsius).all()


def test_a_cold_pixel_past_the_radicand_goes_nan_alone(cal, vendor_frames):
    frame = vendor_frames[0].copy()
    frame[0] = 0x8000  # most negative reading: below absolute zero
    sub = object_temperatures(cal, frame)
    assert sub.failed_pixels == 1 and np.isnan(sub.celsius[0])
    assert np.isfinite(sub.celsius[sub.mask][1:]).all()


def _variant(frame: np.ndarray, pixel_noise: np.ndarray, interleaved: bool, aux: tuple[int, int, int]) -> np.ndarray:
    out = frame.astype(np.int64).copy()
    out[:768] = (out[:768] + pixel_noise) & 0xFFFF
    out[:768][out[:768] == reg.INVALID_WORD] = 0x7FFE
    if interleaved:
        out[reg.RAW_CONTROL] &= ~reg.CONTROL_CHESS
    out[reg.TA_PTAT] += aux[0]
    out[reg.TA_VBE] += aux[1]
    out[reg.VDD_PIX] = (out[reg.VDD_PIX] + aux[2]) & 0xFFFF
    return out.astype(np.uint16)


@given(
    k=st.integers(0, 1),
    noise=arrays(np.int64, 768, elements=st.integers(-400, 400)),
    interleaved=st.booleans(),
    aux=st.tuples(st.integers(-200, 200), st.integers(-2000, 2000), st.integers(-3000, 3000)),
    emissivity=st.floats(0.5, 1.0),
)
def test_vectorised_matches_per_pixel_reference(cal, vendor_frames, k, noise, interleaved, aux, emissivity):
    frame = _variant(vendor_frames[k], noise, interleaved, aux)
    sub = object_temperatures(cal, frame, emissivity=emissivity, reflected_offset_c=-8.0)
    ref = np.array(per_pixel_temperatures(cal, frame.tolist(), emissivity, -8.0))
    assert np.array_equal(np.isnan(sub.celsius), np.isnan(ref))
    finite = np.isfinite(ref)
    assert np.allclose(sub.celsius[finite], ref[finite], rtol=0, atol=1e-9)


def test_one_decoder_reused_across_modes_and_subpages_matches_the_reference(cal, vendor_frames):
    """The decoder slices the calibration once per (mode, sub-page); switching back and forth must not mix them."""
    decoder = Decoder(cal, emissivity=0.95, reflected_offset_c=-5.0)
    rng = np.random.default_rng(3)
    for step in range(8):
        frame = _variant(vendor_frames[step % 2], rng.integers(-50, 50, 768), step // 2 % 2 == 1, (0, 0, 0))
        sub = decoder.decode(frame)
        ref = np.array(per_pixel_temperatures(cal, frame.tolist(), 0.95, -5.0))
        assert sub.mode == ("interleaved" if step // 2 % 2 else "chess") and sub.subpage == step % 2
        assert np.array_equal(np.isnan(sub.celsius), np.isnan(ref))
        assert np.allclose(sub.celsius[sub.mask], ref[sub.mask], rtol=0, atol=1e-9)


def test_out_of_range_words_are_rejected(cal, vendor_frames):
    frame = vendor_frames[0].astype(np.int64)
    frame[5] = -1
    with pytest.raises(FrameRejected) as err:
        object_temperatures(cal, frame)
    assert err.value.reason == "range"


@given(words=arrays(np.uint16, 834))
def test_any_words_decode_or_reject_without_escaping(cal, words):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            sub = object_temperatures(cal, words)
        except FrameRejected:
            return
    assert sub.celsius.shape == (768,)
    assert not np.isinf(sub.celsius).any()
    assert sub.failed_pixels == int(np.isnan(sub.celsius[sub.mask]).sum())
    assert np.isnan(sub.celsius[~sub.mask]).all()
