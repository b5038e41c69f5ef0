"""What ``feelium flight probe`` does: ask a board everything the contract lists, once."""

from __future__ import annotations

from dataclasses import asdict
from typing import Any

from feelium.flight.client import MspClient, MspErrorReply, MspTimeout
from feelium.flight.messages import PayloadError


class ProbeError(RuntimeError):
    """Nothing usable answered: the message says where and what to check."""


def probe_board(port: str | None, sim: bool = False, baudrate: int = 115200, timeout_s: float = 0.5) -> dict[str, Any]:
    if sim:
        import time

        from feelium.flight.sim_board import BoardParams, SimMotorBoard, SimSerial

        clock = time.monotonic
        link: Any = SimSerial(SimMotorBoard(BoardParams(), start_t=clock()), clock)
        where = "simulated motor board"
    else:
        import serial

        assert port is not None
        where = port
        try:
            link = serial.serial_for_url(port, baudrate=baudrate, timeout=min(timeout_s, 0.05), write_timeout=timeout_s)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise ProbeError(f"cannot open {port}: {exc}") from exc
    client = MspClient(link, timeout_s=timeout_s)
    try:
        try:
            version = client.api_version()
        except (MspTimeout, MspErrorReply, PayloadError, OSError) as exc:
            raise ProbeError(
                f"no MSP answer from {where} within {timeout_s} s ({exc}); check the port, the baud rate "
                f"({baudrate}) and that the board's MSP is enabled on that UART"
            ) from exc
        report: dict[str, Any] = {"port": where, "api_version": f"{version.major}.{version.minor}", "msp_protocol": version.protocol}
        errors: dict[str, str] = {}
        queries = {
            "attitude": client.attitude,
            "altitude": client.altitude,
            "rangefinder": client.rangefinder,
            "battery": client.analog,
            "raw_imu": client.raw_imu,
        }
        for name, query in queries.items():
            try:
                report[name] = asdict(query())
            except (MspTimeout, MspErrorReply, PayloadError) as exc:
                report[name] = None
                errors[name] = str(exc)
        try:
            report["motors_us"] = list(client.motors())
        except (MspTimeout, MspErrorReply, PayloadError) as exc:
            report["motors_us"] = None
            errors["motors_us"] = str(exc)
        if errors:
            report["errors"] = errors
        report["link"] = client.health()
        return report
    finally:
        link.close()
