"""``feelium mdns-service``: the avahi service file that advertises the daemon as ``_feelium._tcp``."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import pytest

from feelium.cli import main
from feelium.http.mdns import avahi_service_file


def parsed(xml: str) -> tuple[str, str, int, list[str]]:
    root = ET.fromstring(xml.split("\n", 2)[2])  # past the XML declaration and DOCTYPE, as avahi's parser reads it
    service = root.find("service")
    assert root.tag == "service-group" and service is not None
    name = root.find("name")
    assert name is not None and name.get("replace-wildcards") == "yes"
    return (name.text or "", service.findtext("type") or "", int(service.findtext("port") or 0),
            [t.text or "" for t in service.findall("txt-record")])


def test_the_file_names_the_type_port_path_and_scheme() -> None:
    name, kind, port, txt = parsed(avahi_service_file(8443, tls=True, instance_name="Feelium <lab> & %h"))
    assert (name, kind, port) == ("Feelium <lab> & %h", "_feelium._tcp", 8443)
    assert txt[0] == "txtvers=1" and "path=/api/v1" in txt and "scheme=https" in txt
    assert "scheme=http" in parsed(avahi_service_file(8080, tls=False))[3]


@pytest.mark.parametrize("port", [0, -1, 65536])
def test_a_port_no_client_can_reach_is_refused(port: int) -> None:
    with pytest.raises(ValueError, match="port"):
        avahi_service_file(port, tls=False)


def test_the_command_advertises_the_configured_server(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    config = tmp_path / "feelium.toml"
    config.write_text('[http]\nhost = "0.0.0.0"\nport = 9123\n')
    assert main(["mdns-service", "--config", str(config)]) == 0
    _, _, port, txt = parsed(capsys.readouterr().out)
    assert port == 9123 and "scheme=http" in txt

    config.write_text('[http]\nhost = "0.0.0.0"\nport = 0\n')
    assert main(["mdns-service", "--config", str(config)]) == 1
    assert "port is 0" in capsys.readouterr().err

    config.write_text("[http]\nport = 9123\n")  # the default host, loopback: nobody else could reach it
    assert main(["mdns-service", "--config", str(config)]) == 1
    assert "no other device can reach" in capsys.readouterr().err
