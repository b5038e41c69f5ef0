"""The ``feelium`` command.

Each concern's subcommands live in one module of this package with a
``register(registry)`` function, listed in :data:`COMMAND_MODULES` so a reader
sees every command family in one place (adding one is one visible line).
Those modules keep heavy imports inside their handlers, so ``feelium --help``
stays quick on a Pi and loads neither the daemon nor the lab.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Callable, Sequence
from typing import Any

import feelium
from feelium.recording import RecordingError
from feelium.settings import ConfigError

Handler = Callable[[argparse.Namespace], int]


class CommandRegistry:
    """Where packages add their subcommands (top-level, ``bench X``, ``calibrate X``)."""

    def __init__(self, parser: argparse.ArgumentParser) -> None:
        self._top = parser.add_subparsers(dest="command", metavar="COMMAND")
        self._groups: dict[str, Any] = {}

    def command(self, name: str, help: str, handler: Handler) -> argparse.ArgumentParser:
        """A top-level command ``feelium NAME``."""
        parser = self._top.add_parser(name, help=help, description=help)
        parser.set_defaults(handler=handler)
        return parser

    def group(self, name: str, help: str) -> Any:
        """The subparsers of a command group such as ``bench`` or ``calibrate``."""
        if name not in self._groups:
            parser = self._top.add_parser(name, help=help, description=help)
            parser.set_defaults(handler=lambda args, p=parser: _missing_subcommand(p))
            self._groups[name] = parser.add_subparsers(dest=f"{name}_command", metavar="WHAT")
        return self._groups[name]

    def subcommand(self, group: str, name: str, help: str, handler: Handler) -> argparse.ArgumentParser:
        """``feelium GROUP NAME``, e.g. ``feelium bench touch``."""
        group_help = {
            "bench": "Measure speed against accuracy.",
            "calibrate": "Fit this blimp's parameters from its own data.",
            "config": "Check or show the TOML configuration.",
            "simulate": "Generate labelled datasets with the scene simulator.",
            "thermal": "The MLX90640 thermal camera: live view and offline decoding.",
            "flight": "The motor board and the flight controller.",
            "token": "The headset token (docs/deploy.md, where it is kept).",
        }.get(group, f"feelium {group} commands.")  # never the bare name: that read "token token" in the help
        parser = self.group(group, group_help).add_parser(name, help=help, description=help)
        parser.set_defaults(handler=handler)
        return parser


def _missing_subcommand(parser: argparse.ArgumentParser) -> int:
    parser.print_help(sys.stderr)
    return 2


COMMAND_MODULES = (
    "feelium.cli.daemon",  # run, bench daemon
    "feelium.cli.cameras",  # record, calibrate lens
    "feelium.cli.touch",  # replay, eval, calibrate touch, bench touch
    "feelium.cli.thermal",  # thermal read/decode, bench thermal/presence
    "feelium.cli.flight",  # flight probe, bench flight
    "feelium.cli.projector",  # calibrate projector, bench projector*
    "feelium.cli.http",  # http-url, bench http
    "feelium.cli.sim",  # simulate, bench sim
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="feelium", description="Feelium: onboard software of a touchable blimp.")
    parser.add_argument("--version", action="version", version=f"feelium {feelium.__version__}")
    registry = CommandRegistry(parser)
    _register_config_commands(registry)
    for module_name in COMMAND_MODULES:
        importlib.import_module(module_name).register(registry)
    return parser


def _register_config_commands(registry: CommandRegistry) -> None:
    check = registry.subcommand("config", "check", "Validate a config file; exit 1 naming the key if it is wrong.", _config_check)
    check.add_argument("file", help="TOML config file")
    show = registry.subcommand("config", "show", "Print the effective config (defaults filled in) as TOML.", _config_show)
    show.add_argument("--config", help="TOML config file (default: built-in defaults)")
    show.add_argument("--defaults", action="store_true", help="ignore --config and print the documented defaults")


def _config_check(args: argparse.Namespace) -> int:
    from feelium.daemon.config import load_config

    load_config(args.file)
    print(f"{args.file}: ok")
    return 0


def _config_show(args: argparse.Namespace) -> int:
    from feelium.daemon.config import Config, load_config, render_config

    config = Config() if args.defaults else load_config(args.config)
    sys.stdout.write(render_config(config))
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    handler: Handler | None = getattr(args, "handler", None)
    if handler is None:
        parser.print_help(sys.stderr)
        return 2
    try:
        return int(handler(args) or 0)
    except ConfigError as exc:
        print(f"feelium: config error: {exc}", file=sys.stderr)
        return 1
    except RecordingError as exc:
        print(f"feelium: bad recording: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        return 0


if __name__ == "__main__":
    raise SystemExit(main())
