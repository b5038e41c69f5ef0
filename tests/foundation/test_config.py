"""The config loader: every mistake names the file and the key; the documented file is the defaults."""

from __future__ import annotations

from pathlib import Path

import pytest

from feelium.cli import main
from feelium.daemon.config import Config, beside, load_config, parse_config, render_config
from feelium.settings import ConfigError

REPO = Path(__file__).resolve().parents[2]


def test_defaults_round_trip_through_rendered_toml():
    assert parse_config(render_config(Config())) == Config()


def test_committed_config_file_documents_exactly_the_defaults():
    committed = (REPO / "config" / "feelium.toml").read_text(encoding="utf-8")
    assert committed == render_config(Config()), "regenerate: feelium config show --defaults > config/feelium.toml"


def test_every_setting_is_documented():
    import dataclasses

    def walk(cls, prefix):
        for f in dataclasses.fields(cls):
            if dataclasses.is_dataclass(f.type) or (f.default_factory is not dataclasses.MISSING):
                yield from walk(type(getattr(cls(), f.name)), f"{prefix}{f.name}.")
            else:
                yield prefix + f.name, f.metadata.get("doc", "")

    undocumented = [key for key, doc in walk(Config, "") if not doc]
    assert undocumented == []


@pytest.mark.parametrize(
    ("text", "key", "fragment"),
    [
        ("[touch]\nwidth = 'wide'\n", "touch.width", "expected an integer"),
        ("[touch]\nwidht = 640\n", "touch.widht", "unknown key"),
        ("[http]\nport = 70000\n", "http.port", "out of range"),
        ("[nonsense]\nx = 1\n", "nonsense", "unknown key"),
        ("[interactions]\npalm_area_px = 2500\n", "interactions.palm_area_px", "removed: palms are the touch events' contact"),
        ("[interactions]\nhug_area_px = 12000\n", "interactions.hug_area_px", "hug_min_area_mm2; delete it"),
        ("[daemon]\nlog_level = 'loud'\n", "daemon.log_level", "expected one of"),
        ("touch = 3\n", "touch", "expected a table"),
        ("[touch\n", "(syntax)", ""),
    ],
)
def test_errors_name_file_and_key(tmp_path, text, key, fragment):
    path = tmp_path / "bad.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        load_config(path)
    assert info.value.key == key
    assert str(path) in str(info.value)
    assert fragment in info.value.message


def test_missing_file_is_a_config_error(tmp_path):
    with pytest.raises(ConfigError, match="cannot read"):
        load_config(tmp_path / "absent.toml")


def test_bool_is_not_an_integer():
    with pytest.raises(ConfigError, match="expected an integer"):
        parse_config("[touch]\nwidth = true\n", "x.toml")


def test_config_check_command_exit_codes(tmp_path, capsys):
    good = tmp_path / "good.toml"
    good.write_text("[http]\nport = 9000\n", encoding="utf-8")
    bad = tmp_path / "bad.toml"
    bad.write_text("[http]\nport = -1\n", encoding="utf-8")
    assert main(["config", "check", str(good)]) == 0
    assert main(["config", "check", str(bad)]) == 1
    err = capsys.readouterr().err
    assert "http.port" in err and str(bad) in err


def test_config_show_prints_effective_values(tmp_path, capsys):
    path = tmp_path / "c.toml"
    path.write_text("[http]\nport = 9000\n", encoding="utf-8")
    assert main(["config", "show", "--config", str(path)]) == 0
    shown = capsys.readouterr().out
    assert "port = 9000" in shown
    assert parse_config(shown).http.port == 9000


def test_a_leading_byte_order_mark_is_accepted(tmp_path):
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf[http]\nport = 9000\n")
    assert load_config(path).http.port == 9000


def test_an_empty_file_means_every_default(tmp_path):
    path = tmp_path / "empty.toml"
    path.write_bytes(b"")
    assert load_config(path) == beside(Config(), path)  # every default, the calibration files taken beside it


def test_non_utf8_is_one_line_naming_the_file_and_the_byte(tmp_path, capsys):
    path = tmp_path / "latin1.toml"
    path.write_bytes("[sim]\n# caf\u00e9\n".encode("latin-1"))
    assert main(["config", "check", str(path)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert str(path) in err and "not UTF-8" in err and "0xe9 at offset 11" in err


def test_a_headset_token_too_short_is_refused_by_config_check_naming_the_file(tmp_path, capsys):
    from feelium.cli import main

    path = tmp_path / "feelium.toml"
    path.write_text('[http]\ntoken = "r15token"\n', encoding="utf-8")
    assert main(["config", "check", str(path)]) == 1
    err = capsys.readouterr().err
    assert str(path) in err and "token must be at least 16 characters" in err


def test_relative_calibration_files_are_read_beside_the_config_from_any_working_directory(tmp_path, monkeypatch):
    """`calibrate projector|lens --config X` saves beside X; the daemon started with X elsewhere reads the same."""
    from feelium.skin.projector_map import calibration_path

    folder = tmp_path / "etc"
    folder.mkdir()
    path = folder / "feelium.toml"
    path.write_text('[projector.calibration]\nfile = "maps/p.npz"\n[front_camera]\nlens_file = "/abs/lens.json"\n', encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    config = load_config(path)
    assert calibration_path(config.projector.calibration.file) == folder / "maps" / "p.npz"
    assert calibration_path(config.projector.calibration.file) == calibration_path("maps/p.npz", path)  # where calibrate saves
    assert config.front_camera.lens_file == "/abs/lens.json"  # an absolute path is kept
    assert load_config(None).projector.calibration.file == "projector_calibration.npz"  # no file: the working directory's


@pytest.mark.parametrize("flight, says", [
    ("altitude_min_m = 2.8", "altitude_min_m (2.8) must be below altitude_max_m (2.6)"),
    ("altitude_min_m = 1.0\naltitude_max_m = 1.0", "must be below altitude_max_m (1.0)"),
    ("battery_critical_v = 3.6", "battery_critical_v (3.6) must not be above battery_low_v (3.5)"),
], ids=["floor-above-ceiling", "floor-at-ceiling", "critical-above-low"])
def test_flight_limits_that_contradict_each_other_are_refused_by_config_check_naming_the_file(flight, says, tmp_path, capsys):
    """Each key alone was in its range, so `config check` passed a floor above the ceiling (the session-32 review)."""
    path = tmp_path / "feelium.toml"
    path.write_text(f"[flight]\n{flight}\n", encoding="utf-8")
    assert main(["config", "check", str(path)]) == 1
    err = capsys.readouterr().err
    assert str(path) in err and "flight" in err and says in err
