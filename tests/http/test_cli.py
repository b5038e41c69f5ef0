"""``feelium http-url``: the browser client's address with a token created 0600 on first use, stable afterwards."""

from __future__ import annotations

import stat

from feelium.cli import main


def test_http_url_creates_the_token_once_and_prints_it_in_the_fragment(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    token_file = tmp_path / "cfg" / "token"
    config = tmp_path / "feelium.toml"
    config.write_text(f'[http]\nport = 9123\ntoken_file = "{token_file}"\n')
    assert main(["http-url", "--config", str(config)]) == 0
    first = capsys.readouterr().out.strip()
    token = token_file.read_text().strip()
    assert first == f"http://127.0.0.1:9123/#token={token}"
    assert stat.S_IMODE(token_file.stat().st_mode) == 0o600
    assert main(["http-url", "--config", str(config)]) == 0
    assert capsys.readouterr().out.strip() == first
