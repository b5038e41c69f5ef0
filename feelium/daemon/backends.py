"""What ``auto`` means for each part: the hardware on the blimp, the simulator on a laptop.

On a Raspberry Pi a part set to ``auto`` runs its hardware backend and a
missing device makes that part fail loudly (health ``failed`` with the
reason, an error line in the journal); it never falls back to the simulator,
which would show the wearer phantom touches and fly a blimp that is not
there. Off a Pi, ``auto`` is the simulator, so ``feelium run`` on a laptop
starts a simulated blimp. A part set to ``sim`` (or ``--sim``) is simulated
anywhere; health calls every simulated part ``simulated``.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from feelium.daemon.config import Config

DEVICE_TREE_MODEL = Path("/proc/device-tree/model")
# config section -> (the part it feeds, its hardware backend on the blimp)
HARDWARE = {
    "rear_camera": ("touch", "picamera2"),
    "front_camera": ("front_camera", "picamera2"),
    "thermal": ("thermal", "smbus2"),
    "audio": ("audio", "alsa"),
    "projector": ("projector", "fbdev"),
    "flight": ("flight", "serial"),
}
NOT_HARDWARE = ("sim", "replay")


def on_raspberry_pi(model_file: Path = DEVICE_TREE_MODEL) -> bool:
    """Whether this board is a Raspberry Pi, from the device tree's model string (absent on a laptop)."""
    try:
        return "Raspberry Pi" in model_file.read_bytes().decode("ascii", "replace")
    except OSError:
        return False


def resolve_auto(config: Config, on_pi: bool) -> Config:
    """``config`` with every ``auto`` backend replaced by what it means on this machine."""
    changes: dict[str, Any] = {}
    for name in HARDWARE:
        section = getattr(config, name)
        if section.backend != "auto":
            continue
        if not on_pi:
            changes[name] = dataclasses.replace(section, backend="sim")
        elif name == "front_camera":
            changes[name] = _front_camera_on_pi(section)
        else:
            changes[name] = dataclasses.replace(section, backend=HARDWARE[name][1])
    return dataclasses.replace(config, **changes)


def for_this_machine(config: Config) -> Config:
    """``config`` with ``auto`` resolved for the machine this runs on: what every command that opens a
    device (``record``, ``thermal read``, ``calibrate projector``) applies, so none of them records or
    calibrates the simulator on the blimp when its camera or sensor is missing."""
    return resolve_auto(config, on_raspberry_pi())


def _front_camera_on_pi(section: Any) -> Any:
    """A second CSI camera, else the first USB camera, else the configured device (whose open then fails, loudly)."""
    from feelium.cameras.select import resolve_front_backend

    backend, device = resolve_front_backend(section)
    if backend == "sim":
        backend = "v4l2"
    return dataclasses.replace(section, backend=backend, device=device)


def simulated_parts(config: Config) -> dict[str, str]:
    """Part -> what stands in for its hardware, for every part that runs without it."""
    parts = {}
    for name, (part, _) in HARDWARE.items():
        backend = getattr(config, name).backend
        if backend == "replay":
            parts[part] = f"{name} replays {getattr(config, name).replay_path}"
        elif backend == "sim":
            parts[part] = f"{name} on its simulator"
    return parts


def backend_names(config: Config) -> dict[str, str]:
    """Part -> its backend, for the startup line."""
    return {part: getattr(config, name).backend for name, (part, _) in HARDWARE.items()}
