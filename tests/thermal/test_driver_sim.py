"""The real transport and driver against the simulated sensor: configuration, reads, faults."""

import numpy as np
import pytest
from smbus2 import i2c_msg

from feelium.thermal import registers as reg
from feelium.thermal.calibration import CalibrationError
from feelium.thermal.decoder import FrameAssembler
from feelium.thermal.driver import Mlx90640Driver
from feelium.thermal.sim_device import Faults, SimMlx90640, VirtualClock
from feelium.thermal.transport import SMBus2Transport

SCENE = np.linspace(15.0, 45.0, 768).reshape(24, 32)


def rig(mode="chess", refresh=8.0, faults=None, max_read_words=128, noise=0.3, scene=SCENE, eeprom=None):
    clock = VirtualClock()
    sensor = SimMlx90640(
        scene, clock=clock, sleep=clock.sleep, rng=np.random.default_rng(3), adc_noise_counts=noise, faults=faults,
        eeprom=eeprom,
    )
    transport = SMBus2Transport(sensor.bus(), max_read_words=max_read_words)
    driver = Mlx90640Driver(transport, reg.ControlSettings(refresh, 18, mode))
    return clock, sensor, transport, driver


def run(clock, driver, polls=60, step=0.02):
    asm = FrameAssembler(driver.start())
    images = []
    for _ in range(polls):
        try:
            words = driver.poll()
        except OSError:  # the service counts these and carries on
            clock.sleep(step)
            continue
        if words is None:
            clock.sleep(step)
            continue
        image = asm.add(words)
        if image is not None and asm.complete:
            images.append(image)
    return asm, images


@pytest.mark.parametrize("mode", ["chess", "interleaved"])
def test_scene_round_trips_through_device_words(mode):
    clock, sensor, _, driver = rig(mode)
    asm, images = run(clock, driver)
    assert images, driver.counters
    # one ADC count is about 0.3 degC here: rounding to counts plus 0.3 counts of noise
    err = np.abs(images[-1] - SCENE)
    assert err.max() < 0.6 and err.mean() < 0.15
    assert asm.last.ta == pytest.approx(30.0, abs=0.05)
    assert asm.last.vdd == pytest.approx(3.3, abs=0.002)
    assert asm.last.mode == mode


def test_driver_applies_config_and_never_writes_eeprom():
    clock, sensor, _, driver = rig("interleaved", refresh=4.0)
    run(clock, driver, polls=10)
    settings = reg.ControlSettings.from_word(sensor.control)
    assert settings == reg.ControlSettings(4.0, 18, "interleaved")
    assert sensor.control & reg.CONTROL_SUBPAGES_ENABLED
    assert sensor.eeprom_write_attempts == 0


def test_transport_refuses_eeprom_writes():
    _, sensor, transport, _ = rig()
    with pytest.raises(PermissionError):
        transport.write_word(0x2410, 0x1234)
    assert sensor.eeprom_write_attempts == 0 and sensor.transactions == 0


def test_reads_are_split_and_big_endian():
    _, sensor, transport, _ = rig(max_read_words=100)
    words = transport.read_words(reg.EEPROM_START, 832)
    assert transport.transactions == 9
    assert np.array_equal(words, sensor.eeprom)
    msg = i2c_msg.read(0x33, 2)
    sensor.bus().i2c_rdwr(i2c_msg.write(0x33, [0x24, 0x00]), msg)
    assert bytes(msg) == bytes([sensor.eeprom[0] >> 8, sensor.eeprom[0] & 0xFF])


def test_wrong_device_address_nacks():
    _, sensor, _, _ = rig()
    with pytest.raises(OSError):
        sensor.bus().i2c_rdwr(i2c_msg.write(0x34, [0x80, 0x00]), i2c_msg.read(0x34, 2))


def test_nacks_are_retried_then_reported():
    clock, sensor, _, driver = rig(faults=Faults(nack_next=2))
    driver.start()
    assert driver.health()["retries"] == 2 and driver.health()["io_errors"] == 2
    sensor.faults.nack_next = 3
    with pytest.raises(OSError):
        driver.poll()
    assert driver.health()["io_errors"] == 5


def test_random_nacks_cost_retries_not_frames():
    clock, sensor, _, driver = rig(faults=Faults(nack_rate=0.05))
    _, images = run(clock, driver, polls=120)
    assert driver.health()["retries"] > 0 and len(images) >= 5


def test_invalid_words_are_rejected_by_the_decoder():
    clock, sensor, _, driver = rig(faults=Faults(invalid_word_rate=1.0))
    asm, images = run(clock, driver)
    assert images == [] and asm.rejected.get("invalid_word", 0) == driver.counters.subpages > 0


def test_stale_data_ready_bit_is_detected():
    clock, sensor, _, driver = rig(faults=Faults(stale_ready=True))
    driver.start()
    clock.sleep(0.13)
    assert driver.poll() is not None
    assert driver.poll() is None  # bit still set, nothing new measured
    assert driver.counters.stale == 1
    clock.sleep(0.13)
    assert driver.poll() is not None


def test_slow_bus_tears_reads_and_they_are_dropped():
    # 1 ms per word: a RAM read (832 words) spans 6.7 sub-pages at 8 Hz... so use 64 Hz with 20 us words
    clock, sensor, _, driver = rig(refresh=64.0, faults=Faults(seconds_per_word=20e-6), max_read_words=64)
    asm, images = run(clock, driver, polls=200, step=0.001)
    assert driver.counters.torn > 0
    assert asm.rejected == {}  # torn reads never reached the decoder


def test_garbage_eeprom_is_a_clear_error():
    clock, sensor, _, driver = rig()
    sensor.eeprom[:] = 0xFFFF
    with pytest.raises(CalibrationError, match="0xFFFF"):
        driver.start()


def test_power_on_ram_is_not_decoded():
    clock, sensor, _, driver = rig()
    driver.start()
    assert driver.poll() is None  # nothing measured yet: no new-data bit
    assert driver.counters.not_ready == 1


def _word_by_word(sensor: SimMlx90640, address: int, count: int) -> list[int]:
    """What a read returns, by the register map one word at a time: the definition the device's range copy must meet."""
    out = []
    for a in range(address, address + count):
        if reg.EEPROM_START <= a <= reg.EEPROM_END:
            out.append(int(sensor.eeprom[a - reg.EEPROM_START]))
        elif reg.RAM_START <= a <= reg.RAM_END:
            out.append(int(sensor.ram[a - reg.RAM_START]))
        else:
            out.append({reg.STATUS: sensor.status, reg.CONTROL: sensor.control, reg.I2C_CONFIG: sensor.i2c_config}.get(a, 0))
    return out


@pytest.mark.parametrize(
    "address, count",
    [(reg.RAM_START, reg.RAM_WORDS), (reg.EEPROM_START, reg.EEPROM_WORDS), (reg.STATUS, 1), (reg.CONTROL, 3),
     (reg.RAM_START - 5, 20), (reg.RAM_END - 3, 10), (reg.EEPROM_START - 2, 5), (reg.EEPROM_END - 1, 4),
     (reg.STATUS - 2, 18), (0, 3), (reg.RAM_START + 700, 132)],
)
def test_a_read_returns_the_register_map_word_by_word(address: int, count: int) -> None:
    clock, sensor, _, driver = rig()
    run(clock, driver, polls=12)  # RAM holds a measured sub-page, status and control are set
    assert sensor.read(address, count).tolist() == _word_by_word(sensor, address, count)
