"""Which request a reply answers: MSP's in-order rule over a FIFO of outstanding requests.

MSP has no sequence numbers: the board answers one request with one reply, in
order (``docs/motor-board.md``). A reply therefore answers the oldest
outstanding request of its command, and the older requests it overtook are
lost. This module holds that rule and the small records the client keeps;
the client (``client.py``) owns the line, the timing and the counters.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import NamedTuple

from feelium.flight import messages as m
from feelium.flight.msp import MspFrame


class Outstanding(NamedTuple):
    """A request written and not yet answered: its command, when and in which burst it went out.

    A named tuple (six are built a tick): a frozen dataclass cost twice as much to build."""

    command: int
    written_t: float
    burst: int


@dataclass
class Burst:
    """One exchange: its number, write time, the replies that answered it and what else the line carried."""

    number: int
    t: float = 0.0
    replies: dict[int, MspFrame] = field(default_factory=dict)
    heard: bool = False
    stale_bytes: int = 0
    late: int = 0
    lost: int = 0
    unmatched: int = 0

    @property
    def disordered(self) -> bool:
        """Stale bytes, late replies or requests overtaken: the line did not answer this burst as it should."""
        return bool(self.stale_bytes or self.late or self.lost)


def wire_size(frame: MspFrame) -> int:
    """Bytes the frame took on the line (header, payload, checksum)."""
    return (9 if frame.version == 2 else 6) + len(frame.payload)


def is_ack(frame: MspFrame) -> bool:
    """The board's (empty or error) answer to MSP_SET_MOTOR: it carries no telemetry."""
    return frame.direction != "<" and frame.command == m.MSP_SET_MOTOR


def take_reply(outstanding: deque[Outstanding], command: int, newest: int, decides: bool) -> tuple[Outstanding | None, int]:
    """Pop the oldest outstanding request of ``command`` from burst ``newest`` or before; ``(None, 0)`` if none.

    Returns the request and how many older requests it overtook (lost). Only a reply that
    ``decides`` drops those: an ack never does, since motor commands written while
    resynchronising are not tracked, so an ack may belong to one of them, and dropping
    telemetry requests on its word would let their replies, when they come, pass for a
    later burst's.
    """
    for index, request in enumerate(outstanding):
        if request.burst > newest:
            return None, 0
        if request.command == command:
            if not decides:
                del outstanding[index]
                return request, 0
            for _ in range(index):
                outstanding.popleft()
            return outstanding.popleft(), index
    return None, 0
