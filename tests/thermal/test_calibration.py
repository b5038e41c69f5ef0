"""EEPROM sanity checks: a dump that cannot be a device's is a clear error, never garbage temperatures."""

import numpy as np
import pytest

from feelium.thermal.calibration import CalibrationError, extract_calibration


def with_pixel_words(ee: np.ndarray, changes: dict[int, int]) -> np.ndarray:
    ee = ee.copy()
    for pixel, word in changes.items():
        ee[64 + pixel] = word
    return ee


def test_all_ones_dump_is_rejected(vendor_eeprom_words):
    with pytest.raises(CalibrationError, match="all 0xFFFF"):
        extract_calibration(np.full(832, 0xFFFF, dtype=np.uint16))


def test_all_zero_dump_is_rejected():
    with pytest.raises(CalibrationError, match="all zero"):
        extract_calibration(np.zeros(832, dtype=np.uint16))


def test_wrong_length_is_rejected(vendor_eeprom_words):
    with pytest.raises(CalibrationError, match="832 words"):
        extract_calibration(vendor_eeprom_words[:800])


def test_zero_kvdd_is_impossible(vendor_eeprom_words):
    ee = vendor_eeprom_words.copy()
    ee[51] &= 0x00FF
    with pytest.raises(CalibrationError, match="kVdd"):
        extract_calibration(ee)


def test_zero_ktptat_is_impossible(vendor_eeprom_words):
    ee = vendor_eeprom_words.copy()
    ee[50] &= 0xFC00
    with pytest.raises(CalibrationError, match="KtPTAT"):
        extract_calibration(ee)


def test_up_to_four_separated_deviating_pixels_are_accepted(vendor_eeprom_words):
    ee = with_pixel_words(vendor_eeprom_words, {40: 0, 300: 0, 500: vendor_eeprom_words[64 + 500] | 1, 700: 0})
    cal = extract_calibration(ee)
    assert cal.broken_pixels == (40, 300, 700)
    assert cal.outlier_pixels == (500,)


def test_more_than_four_deviating_pixels_is_an_error(vendor_eeprom_words):
    ee = with_pixel_words(vendor_eeprom_words, {40: 0, 140: 0, 300: 0, 500: 0, 700: 0})
    with pytest.raises(CalibrationError, match="5 deviating pixels"):
        extract_calibration(ee)


@pytest.mark.parametrize("other", [41, 72, 73, 71, 8])  # right, below, diagonal, diagonal, above
def test_adjacent_deviating_pixels_are_an_error(vendor_eeprom_words, other):
    ee = with_pixel_words(vendor_eeprom_words, {40: 0, other: vendor_eeprom_words[64 + other] | 1})
    with pytest.raises(CalibrationError, match="adjacent"):
        extract_calibration(ee)


def test_pixels_on_row_ends_are_not_adjacent(vendor_eeprom_words):
    # pixel 31 ends row 0 and pixel 32 starts row 1: far apart on the sensor
    cal = extract_calibration(with_pixel_words(vendor_eeprom_words, {31: 0, 32: 0}))
    assert cal.broken_pixels == (31, 32)
