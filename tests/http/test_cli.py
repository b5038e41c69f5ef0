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


def test_http_url_on_all_interfaces_lists_every_address_and_the_local_name(tmp_path, capsys, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    from feelium.http import service

    monkeypatch.setattr(service, "interface_ipv4", lambda: ["127.0.0.1", "192.168.1.50", "10.0.0.7"])
    monkeypatch.setattr(service.socket, "gethostname", lambda: "blimp")
    config = tmp_path / "feelium.toml"
    config.write_text('[http]\nhost = "0.0.0.0"\nport = 8080\ntoken = "a-token-of-sixteen-chars"\n')
    assert main(["http-url", "--config", str(config)]) == 0
    assert capsys.readouterr().out.split() == [
        f"http://{host}:8080/#token=a-token-of-sixteen-chars" for host in ("192.168.1.50", "10.0.0.7", "127.0.0.1", "blimp.local")
    ]


def test_interfaces_are_read_from_the_kernel() -> None:
    from feelium.http.addresses import interface_ipv4, reachable_hosts

    found = interface_ipv4()
    assert "127.0.0.1" in found  # every Linux box has loopback; the others depend on the machine
    assert reachable_hosts("0.0.0.0", found, "h")[-2:] == ["127.0.0.1", "h.local"]
    assert reachable_hosts("192.168.1.50", found, "h") == ["192.168.1.50"]
