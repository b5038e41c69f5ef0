"""Finding the daemon's services: every ``feelium/<package>/service.py`` with a ``build_services``.

Like the CLI's command discovery, adding a part never edits a central list. A
package whose module fails to import or build is reported (logged with its
traceback and listed in health) and the rest of the blimp still starts.
"""

from __future__ import annotations

import importlib
import importlib.util
import logging
import pkgutil
from dataclasses import dataclass, field

import feelium
from feelium.config import Config
from feelium.hub import Hub
from feelium.service import Service

log = logging.getLogger(__name__)


@dataclass
class Discovered:
    services: list[Service] = field(default_factory=list)
    failures: dict[str, str] = field(default_factory=dict)  # module -> "ErrorType: message"


def service_modules() -> list[str]:
    """Every ``feelium.<package>.service`` module, in a stable order."""
    names = []
    for info in pkgutil.iter_modules(feelium.__path__):
        if info.ispkg and importlib.util.find_spec(f"feelium.{info.name}.service") is not None:
            names.append(f"feelium.{info.name}.service")
    return sorted(names)


def build_all(config: Config, hub: Hub, modules: list[str] | None = None) -> Discovered:
    """Import each service module and build its services; failures are collected, never raised."""
    found = Discovered()
    for module_name in service_modules() if modules is None else modules:
        try:
            module = importlib.import_module(module_name)
            build = getattr(module, "build_services", None)
            if build is None:
                raise TypeError(f"{module_name} defines no build_services(config, hub)")
            services = list(build(config, hub))
            for service in services:
                if not isinstance(service, Service):
                    raise TypeError(f"{module_name} built {service!r}, which is not a Service (name, stop_order, run, stop, health)")
        except Exception as exc:
            log.error("cannot start %s: %s", module_name, exc, exc_info=True)
            found.failures[module_name] = f"{type(exc).__name__}: {exc}"
            continue
        names = {s.name for s in found.services}
        for service in services:
            if service.name in names:
                found.failures[module_name] = f"duplicate service name {service.name!r}"
                log.error("cannot start %s: duplicate service name %r", module_name, service.name)
                break
        else:
            found.services.extend(services)
            log.debug("%s: %s", module_name, ", ".join(s.name for s in services) or "nothing to run (off in the config)")
    return found
