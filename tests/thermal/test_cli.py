"""The thermal commands: decode a recording's raw words, read from the simulated sensor, bench and presence report."""

import json

import numpy as np

from feelium.cli import main


def test_decode_vendor_words_to_temperatures(tmp_path, vendor, vendor_eeprom_words, vendor_frames, capsys):
    raw = tmp_path / "raw.npz"
    bad = vendor_frames[0].copy()
    bad[0] = 0x7FFF
    ram = np.stack([vendor_frames[0], vendor_frames[1], bad])
    np.savez(raw, eeprom=vendor_eeprom_words, ram=ram, t=np.array([0.0, 0.5, 1.0]))
    out = tmp_path / "out.npz"
    assert main(["thermal", "decode", str(raw), "--out", str(out), "--json", "--emissivity", "1.0"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["decoded"] == 2 and summary["rejected"] == {"invalid_word": 1}
    assert summary["frames_detail"][0]["vdd"] == vendor["expected_intermediate"]["frame_0"]["vdd"]
    assert summary["calibration"]["gainEE"] == 5580
    with np.load(out) as data:
        celsius = data["celsius"]
        assert celsius.shape == (3, 24, 32) and celsius.dtype == np.float32
        assert np.abs(celsius[1] - np.array(vendor["expected_to_after_frame_1"])).max() < 0.01
        assert np.isnan(celsius[2]).all()  # the rejected frame has no valid reading
        assert data["ram"].shape == (3, 834)


def test_decode_rejects_bad_inputs_clearly(tmp_path, capsys):
    raw = tmp_path / "raw.npz"
    np.savez(raw, eeprom=np.full(832, 0xFFFF, dtype=np.uint16), ram=np.zeros((2, 834), dtype=np.uint16))
    assert main(["thermal", "decode", str(raw)]) == 1
    assert "all 0xFFFF" in capsys.readouterr().err
    np.savez(raw, celsius=np.zeros((1, 24, 32)))
    assert main(["thermal", "decode", str(raw)]) == 1
    assert "needs arrays" in capsys.readouterr().err


def test_read_sim_prints_heat_maps(capsys):
    assert main(["thermal", "read", "--sim", "--frames", "2", "--colors", "256"]) == 0
    out = capsys.readouterr().out
    assert out.count("Ta ") == 2 and out.count("\n") == 2 * 13
    assert "\x1b[38;5;" in out and "\u2580" in out


def test_bench_thermal_reports_both_and_ratio(tmp_path, capsys):
    path = tmp_path / "bench.json"
    assert main(["bench", "thermal", "--repeats", "5", "--baseline-repeats", "2", "--json", str(path)]) == 0
    result = json.loads(path.read_text())
    assert result["vectorised"]["runs"] == 5 and result["per_pixel_python"]["runs"] == 2
    assert result["speedup_median"] > 0 and result["max_abs_difference_c"] < 1e-9
    assert "speed-up" in capsys.readouterr().out


def test_bench_presence_small_run(capsys):
    assert main(["bench", "presence", "--approach", "3", "--empty", "1", "--empty-seconds", "60", "--json", "-"]) == 0
    out = capsys.readouterr().out
    report = json.loads(out[out.index("\n{\n") + 1 :])
    assert report["clips"]["approach"] == 3 and report["false_alarms_per_hour"] is not None


def test_decode_takes_emissivity_from_the_config(tmp_path, vendor_eeprom_words, vendor_frames, capsys):
    raw = tmp_path / "raw.npz"
    np.savez(raw, eeprom=vendor_eeprom_words, ram=np.stack(vendor_frames))
    config = tmp_path / "feelium.toml"
    temps = {}
    for emissivity in (1.0, 0.9):
        config.write_text(f"[thermal]\nemissivity = {emissivity}\n")
        out = tmp_path / f"out-{emissivity}.npz"
        assert main(["thermal", "decode", str(raw), "--config", str(config), "--out", str(out), "--json"]) == 0
        assert json.loads(capsys.readouterr().out)["emissivity"] == emissivity
        with np.load(out) as data:
            temps[emissivity] = data["celsius"][1]
    assert np.all(temps[0.9] > temps[1.0])  # the vendor scene is warmer than its surroundings


def test_read_without_a_bus_says_what_to_do(tmp_path, capsys):
    config = tmp_path / "feelium.toml"
    config.write_text('[thermal]\nbackend = "smbus2"\ni2c_bus = 250\n')  # no /dev/i2c-250 anywhere
    assert main(["thermal", "read", "--frames", "1", "--config", str(config)]) == 1
    err = capsys.readouterr().err
    assert "/dev/i2c-250" in err and "i2c_arm=on" in err and "--sim" in err


def test_read_on_a_pi_with_auto_reads_the_bus_never_the_simulator(tmp_path, monkeypatch, capsys):
    import feelium.daemon.backends as backends

    monkeypatch.setattr(backends, "on_raspberry_pi", lambda: True)
    config = tmp_path / "feelium.toml"
    config.write_text("[thermal]\ni2c_bus = 250\n")  # backend auto (the default); no /dev/i2c-250 anywhere
    assert main(["thermal", "read", "--frames", "1", "--config", str(config)]) == 1
    err = capsys.readouterr().err
    assert "/dev/i2c-250" in err and "simulated" not in err
