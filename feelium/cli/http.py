"""``feelium http url`` (the browser client's address with the token) and ``feelium bench http``."""

from __future__ import annotations

import argparse

from feelium.cli import CommandRegistry


def register(registry: CommandRegistry) -> None:
    http = registry.command("http-url", "Print the browser client's URL at every reachable address, with the headset token (creates it on first use).", _url)
    http.add_argument("--config", help="TOML config file (default: built-in defaults)")
    bench = registry.subcommand(
        "bench", "http", "Headset link: motion round trip, touch-event latency per transport, MJPEG fps with a stalled client.", _bench
    )
    bench.add_argument("--requests", type=int, default=300, help="motion requests and touch events per transport (default 300)")
    bench.add_argument("--seconds", type=float, default=4.0, help="MJPEG measuring time per phase (default 4)")
    bench.add_argument("--fps", type=float, default=30.0, help="rate of the synthetic 640x480 front video (default 30)")
    bench.add_argument("--json", metavar="FILE", help="also write the results as JSON here")


def _url(args: argparse.Namespace) -> int:
    from feelium.daemon.config import load_config
    from feelium.http.auth import load_or_create_token
    from feelium.http.service import client_urls

    config = load_config(args.config).http
    for url in client_urls(config, token=load_or_create_token(config.token, config.token_file)):
        print(url)
    return 0


def _bench(args: argparse.Namespace) -> int:
    from feelium.lab.http.bench import bench_http_command

    return bench_http_command(args)
