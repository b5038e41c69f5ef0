"""``feelium http-url``, ``feelium pair``, ``feelium mdns-service``, ``feelium token rotate`` and ``feelium bench link``."""

from __future__ import annotations

import argparse
import sys

from feelium.cli import CommandRegistry


def register(registry: CommandRegistry) -> None:
    http = registry.command("http-url", "Print the browser client's URL at every reachable address, with the headset token (creates it on first use).", _url)
    http.add_argument("--config", help="TOML config file (default: built-in defaults)")
    pair = registry.command(
        "pair", "Ask the running daemon for a one-time pairing code the headset exchanges for the token.", _pair
    )
    pair.add_argument("--config", help="TOML config file (default: built-in defaults)")
    mdns = registry.command(
        "mdns-service",
        "Print the avahi service file that advertises this daemon as _feelium._tcp (docs/deploy.md, Bonjour).",
        _mdns,
    )
    mdns.add_argument("--config", help="TOML config file (default: built-in defaults)")
    rotate = registry.subcommand(
        "token", "rotate", "Write a new headset token; the running daemon uses it within a second, the old one stops working.", _rotate
    )
    rotate.add_argument("--config", help="TOML config file (default: built-in defaults)")
    for name, help in (
        ("link", "Headset link: motion round trip, stop under a flood, touch-event latency per transport, MJPEG fps with a stalled client, speech delay and jitter, RSS under abuse."),
        ("http", "The same as `feelium bench link` (its former name)."),
    ):  # fmt: skip
        bench = registry.subcommand("bench", name, help, _bench)
        bench.add_argument("--requests", type=int, default=300, help="motion requests and touch events per transport (default 300)")
        bench.add_argument("--seconds", type=float, default=4.0, help="MJPEG measuring time per phase (default 4)")
        bench.add_argument("--fps", type=float, default=30.0, help="rate of the synthetic 640x480 front video (default 30)")
        bench.add_argument("--speech-seconds", type=float, default=10.0,
                           help="speech streamed vs long-polled, measured together for this long (default 10)")
        bench.add_argument("--no-abuse", action="store_true",
                           help="skip the abuse phase (a real sim daemon under hostile clients, its RSS per phase; ~30 s)")
        bench.add_argument("--json", metavar="FILE", help="also write the results as JSON here")

def _url(args: argparse.Namespace) -> int:
    from feelium.daemon.config import load_config
    from feelium.http.auth import load_or_create_token
    from feelium.http.service import client_urls

    config = load_config(args.config).http
    for url in client_urls(config, token=load_or_create_token(config.token, config.token_file)):
        print(url)
    return 0


def _mdns(args: argparse.Namespace) -> int:
    from feelium.daemon.config import load_config
    from feelium.http.mdns import avahi_service_file

    config = load_config(args.config).http
    if config.port == 0:
        print("feelium mdns-service: [http] port is 0 (any free port); advertise a fixed port", file=sys.stderr)
        return 1
    if config.host.startswith("127.") or config.host in ("localhost", "::1"):
        print(f"feelium mdns-service: [http] host is {config.host}, which no other device can reach; bind 0.0.0.0 "
              "(or the Wi-Fi address) before advertising the blimp", file=sys.stderr)  # fmt: skip
        return 1
    sys.stdout.write(avahi_service_file(config.port, tls=bool(config.tls_cert)))
    return 0


def _pair(args: argparse.Namespace) -> int:
    import json
    import ssl
    import urllib.error
    import urllib.request

    from feelium.daemon.config import load_config
    from feelium.http.addresses import WILDCARD_HOSTS, url_host
    from feelium.http.auth import load_or_create_token
    from feelium.http.service import client_urls

    config = load_config(args.config).http
    token = load_or_create_token(config.token, config.token_file)
    host = "127.0.0.1" if config.host in WILDCARD_HOSTS else config.host
    scheme = "https" if config.tls_cert else "http"
    url = f"{scheme}://{url_host(host)}:{config.port}/api/v1/pair/code"
    context = None
    if config.tls_cert:  # our own daemon on this machine: its certificate need not name the address we dial
        context = ssl.create_default_context()
        context.check_hostname = False
        context.verify_mode = ssl.CERT_NONE
    request = urllib.request.Request(url, method="POST", headers={"Authorization": f"Bearer {token}"})
    try:
        with urllib.request.urlopen(request, timeout=5, context=context) as resp:
            answer = json.load(resp)
    except (urllib.error.URLError, OSError, ValueError) as exc:
        print(f"feelium: cannot get a pairing code from {url}: {exc}; is `feelium run` running with this config?", file=sys.stderr)
        return 1
    print(f"pairing code: {answer['code']}  (works once, for {answer['expires_in_s']:g} s)")
    print("In the headset app, enter the blimp's address and this code. The blimp is at:")
    for address in client_urls(config):
        print(f"  {address}")
    if config.tls_cert:
        return _print_pin(config.tls_cert, host, config.port)
    return 0


def _print_pin(cert_path: str, host: str, port: int) -> int:
    """The certificate fingerprint the headset pins, checked against what the running daemon serves."""
    from feelium.http.certificate import pem_file_fingerprint, served_fingerprint

    try:
        pin, served = pem_file_fingerprint(cert_path), served_fingerprint(host, port)
    except (OSError, ValueError) as exc:
        print(f"feelium: cannot read the certificate's fingerprint: {exc}", file=sys.stderr)
        return 1
    print(f"certificate SHA-256 (pin it in the headset app): {pin}")
    if served != pin:
        print(f"feelium: the daemon serves another certificate ({served}) than {cert_path}: restart it "
              "(`systemctl restart feelium`) before pinning", file=sys.stderr)  # fmt: skip
        return 1
    return 0


def _rotate(args: argparse.Namespace) -> int:
    from feelium.daemon.config import load_config
    from feelium.http.auth import TokenError, write_new_token

    config = load_config(args.config).http
    if config.token:
        print("feelium: the token is set in [http] token: change it there and restart the daemon", file=sys.stderr)
        return 1
    try:
        write_new_token(config.token_file)
    except TokenError as exc:
        print(f"feelium: {exc}", file=sys.stderr)
        return 1
    print(f"new token written to {config.token_file}; the daemon uses it within a second. Pair the headset again (feelium pair).")
    return 0


def _bench(args: argparse.Namespace) -> int:
    from feelium.lab.http.bench import bench_http_command

    return bench_http_command(args)
