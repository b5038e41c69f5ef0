"""The MSP client: requests, replies and the one pipelined exchange a control cycle needs.

It is synchronous on purpose: the service runs it on its one serial thread
with a short read timeout, so the event loop never
blocks, and the same code runs unchanged against pyserial, Betaflight SITL
and the simulated board. A control cycle writes the motor command and all
telemetry requests in one burst and collects the replies until a deadline,
so one 115200-baud cycle costs about one round trip, not six.

MSP has no sequence numbers, so a reply is attributed by order: the board
answers one request with one reply, in order (``docs/motor-board.md``; the
rule itself is ``replies.py``, the payload decoding ``telemetry_decode.py``).
Every request written is kept in a FIFO of outstanding requests; a reply
pops the oldest outstanding request of its command, and the older ones it
overtook are lost. A reply to a request of an earlier burst is *late*: it is
counted and never used, so telemetry is never older than the burst it
claims to answer (``Telemetry.t`` is that burst's write time).

A board that stalls and then answers seconds of buffered requests must not
leave a backlog behind. Before each burst whatever is already waiting is
read and, apart from motor acknowledgements, counted as stale. When the
FIFO outgrows its bound, stale bytes keep arriving or a reply answers
nothing we asked, the client *resynchronises*: it discards the input,
forgets the outstanding requests and sends no telemetry requests until
replies to the forgotten ones can no longer come, so none can pass for a new
one: the line must have been quiet (nothing but motor acknowledgements) for
``quiet_s``, and, since a quiet spell proves little on a board that lags, in
order, either every request written has been answered or a motor command
written after the resync began has been acknowledged (motor commands keep
going out, so that proof comes within a round trip). A board silent for
``stall_bursts`` bursts is *stalled*: nothing is tracked, one small probe
goes out per poll, and the first bytes heard again start a resynchronisation
(they may be the stall's backlog).

Since a stray or torn frame can still shift the attribution by one, the
rangefinder request moves through the burst from cycle to cycle, so a shift
shows as replies that overtake requests or match none; a burst in which a
reply overtook a request is not used, and repeated ones resynchronise.
"""

from __future__ import annotations

import functools
import time
from collections import deque
from collections.abc import Callable, Iterable
from typing import Literal, NamedTuple

from feelium.flight import messages as m
from feelium.flight.msp import MspFrame, MspParser, encode_v2
from feelium.flight.replies import Burst, Outstanding, is_ack, take_reply, wire_size
from feelium.flight.telemetry import Telemetry
from feelium.flight.telemetry_decode import decode_telemetry
from feelium.flight.transport import ByteLink, read_some_of


class MspTimeout(TimeoutError):
    """The board did not answer in time."""


class MspErrorReply(RuntimeError):
    """The board answered a request with an error frame (it does not support the command)."""


POLL_COMMANDS = (m.MSP_SONAR_ALTITUDE, m.MSP_ATTITUDE, m.MSP_RAW_IMU, m.MSP2_SENSOR_OPTIC_FLOW)
_SET_MOTOR = m.MSP_SET_MOTOR
# Three bursts' worth: the poll commands, the battery and the motor command of each cycle.
MAX_OUTSTANDING = 3 * (len(POLL_COMMANDS) + 2)
STALL_BURSTS = 3
STALE_BURSTS = 3
PROBE_COMMAND = m.MSP_API_VERSION  # every board answers it; one small frame per poll while stalled

LinkState = Literal["up", "stalled", "resyncing"]


class _Requests(NamedTuple):
    """One poll's requests and their bytes on the line, built once for each order (a control tick asks one)."""

    commands: tuple[int, ...]  # in order, each a telemetry request without payload
    wire: bytes


@functools.lru_cache(maxsize=16)
def _poll_burst(rangefinder_at: int, with_battery: bool) -> _Requests:
    """The telemetry requests with the rangefinder's at ``rangefinder_at`` (see ``MspClient._poll_requests``)."""
    commands = [command for command in POLL_COMMANDS if command != m.MSP_SONAR_ALTITUDE]
    if with_battery:
        commands.append(m.MSP_ANALOG)
    commands.insert(rangefinder_at, m.MSP_SONAR_ALTITUDE)
    return _Requests(tuple(commands), b"".join(encode_v2(command) for command in commands))


class MspClient:
    """Talks MSP v2 over a :class:`ByteLink`; counts what went wrong instead of raising mid-flight."""

    def __init__(
        self,
        link: ByteLink,
        timeout_s: float = 0.05,
        clock: Callable[[], float] = time.monotonic,
        max_outstanding: int = MAX_OUTSTANDING,
        quiet_s: float | None = None,
        stall_bursts: int = STALL_BURSTS,
        stale_bursts: int = STALE_BURSTS,
    ) -> None:
        self.link = link
        self._read_some = read_some_of(link)
        self.timeout_s = timeout_s
        self.clock = clock
        self.max_outstanding = max_outstanding
        self.quiet_s = 2.0 * timeout_s if quiet_s is None else quiet_s
        self.stall_bursts = stall_bursts
        self.stale_bursts = stale_bursts
        self.parser = MspParser()
        self.state: LinkState = "up"
        self.timeouts = 0
        self.unexpected_replies = 0
        self.error_replies: dict[int, int] = {}
        self.bad_payloads = 0
        self.motor_commands_sent = 0
        self.motor_acks = 0
        self.motor_rejections = 0
        self.late_replies = 0
        self.lost_requests = 0
        self.stale_bytes = 0
        self.stalls = 0
        self.resyncs = 0
        self.last_reply_t: float | None = None  # when poll() last collected in-time replies
        self.telemetry_t: float | None = None  # write time of the newest burst poll() used replies from
        self._outstanding: deque[Outstanding] = deque()
        self._bursts = 0
        self._silent_bursts = 0
        self._stale_run = 0
        self._noise_t = 0.0
        # Replies still owed for everything written (telemetry-type and motor acks), whether tracked or forgotten.
        self._replies_owed = 0
        self._acks_owed = 0
        self._acks_owed_at_resync = 0
        self._acks_since_resync = 0
        self._motors_at_resync = 0

    @property
    def stalled(self) -> bool:
        """No byte came back for the last ``stall_bursts`` bursts (and none since)."""
        return self.state == "stalled"

    # ---- single requests (probe, conformance tests) ----
    def request(self, command: int, payload: bytes = b"") -> MspFrame:
        """Send one request and return its reply; raises :class:`MspTimeout` or :class:`MspErrorReply`.

        A request that went unanswered leaves the line in doubt (was it lost, or is its reply
        still coming?), so the next one waits for a quiet line first: a retried command must
        not take, or be taken for, the earlier one's reply.
        """
        name = f"MSP command {command} ({m.COMMAND_NAMES.get(command, '?')})"
        if not self._wait_settled():
            raise MspTimeout(f"the line did not go quiet within {self.quiet_s + self.timeout_s} s before {name}")
        replies = self.exchange([(command, payload)])
        frame = replies.get(command)
        if frame is None:
            self._resync(self.clock())
            raise MspTimeout(f"no reply to {name} within {self.timeout_s} s")
        if frame.is_error:
            raise MspErrorReply(f"board rejected {name}")
        return frame

    def api_version(self) -> m.ApiVersion:
        return m.ApiVersion.decode(self.request(m.MSP_API_VERSION).payload)

    def attitude(self) -> m.Attitude:
        return m.Attitude.decode(self.request(m.MSP_ATTITUDE).payload)

    def altitude(self) -> m.Altitude:
        return m.Altitude.decode(self.request(m.MSP_ALTITUDE).payload)

    def rangefinder(self) -> m.Rangefinder:
        return m.Rangefinder.decode(self.request(m.MSP_SONAR_ALTITUDE).payload)

    def raw_imu(self) -> m.RawImu:
        return m.RawImu.decode(self.request(m.MSP_RAW_IMU).payload)

    def analog(self) -> m.Analog:
        return m.Analog.decode(self.request(m.MSP_ANALOG).payload)

    def motors(self) -> tuple[int, ...]:
        return m.decode_motors(self.request(m.MSP_MOTOR).payload)

    def set_motors(self, values_us: Iterable[int]) -> None:
        self.request(m.MSP_SET_MOTOR, m.encode_motors(list(values_us)))

    # ---- the pipelined exchange ----
    def exchange(self, requests: list[tuple[int, bytes]]) -> dict[int, MspFrame]:
        """Write every request at once, then collect this burst's replies (by command) until all came or time ran out.

        Replies to earlier bursts met on the way are counted as late and left out.
        """
        return self._exchange(requests).replies

    def _exchange(self, requests: list[tuple[int, bytes]] | _Requests) -> Burst:
        """Write the burst, then read what was already waiting before it, then collect its replies.

        The waiting bytes are only counted before the write and read after it, so the write
        goes out first (a read may block) and they still cannot answer this burst.
        """
        burst = Burst(self._bursts + 1)
        waiting = self.link.in_waiting
        self._write_burst(burst, requests)
        self._drain(burst, waiting)
        self._collect(burst)
        return burst

    def _drain(self, burst: Burst, waiting: int) -> None:
        """Read what waited before the burst: acks and late replies pop their requests, the rest is stale."""
        data = self.link.read(waiting) if waiting else b""
        if not data:
            return
        burst.heard = True
        frames = self._frames(data)
        for frame in frames:
            self._receive(frame, burst, newest=burst.number - 1)
        stale = len(data) - sum(wire_size(f) for f in frames if is_ack(f))
        burst.stale_bytes = max(stale, 0)
        self.stale_bytes += burst.stale_bytes

    def _write_burst(self, burst: Burst, requests: list[tuple[int, bytes]] | _Requests) -> None:
        burst.t = self.clock()
        self._bursts = burst.number
        if isinstance(requests, _Requests):  # a poll's burst, encoded once; telemetry requests only
            self.link.write(requests.wire)
            written_t, number = burst.t, burst.number
            self._outstanding.extend([Outstanding(command, written_t, number) for command in requests.commands])
            self._replies_owed += len(requests.commands)
            return
        self.link.write(b"".join(encode_v2(command, payload) for command, payload in requests))
        self._outstanding.extend(Outstanding(command, burst.t, burst.number) for command, _ in requests)
        motors = sum(command == m.MSP_SET_MOTOR for command, _ in requests)
        self._acks_owed += motors
        self._replies_owed += len(requests) - motors

    def _collect(self, burst: Burst) -> None:
        deadline = burst.t + self.timeout_s
        while any(r.burst == burst.number for r in self._outstanding):
            data = self._read_some()
            burst.heard |= bool(data)
            for frame in self._frames(data):
                self._receive(frame, burst, newest=burst.number)
            if not data and self.clock() >= deadline:
                self.timeouts += 1
                self.parser.abandon()
                return
        self._replies_owed = self._acks_owed = 0  # answered in full: in order, nothing written before is still coming

    def _frames(self, data: bytes) -> list[MspFrame]:
        """Parse what came in and settle the replies owed (every read goes through here)."""
        frames = self.parser.feed(data)
        for frame in frames:
            if frame.direction == "<":
                continue
            if frame.command == _SET_MOTOR:  # an ack (is_ack, inlined: ~6 frames a tick come through here)
                self._acks_owed = max(0, self._acks_owed - 1)
                self._acks_since_resync += 1
            else:
                self._replies_owed = max(0, self._replies_owed - 1)
        return frames

    def _receive(self, frame: MspFrame, burst: Burst, newest: int) -> None:
        """Attribute one frame to the request it answers (of burst ``newest`` or older); only replies to ``burst`` are kept."""
        if frame.direction == "<":
            self.unexpected_replies += 1  # our own requests echoed back (e.g. loop://)
            return
        command = frame.command
        if command == _SET_MOTOR:  # an ack: it never decides that the requests it overtook were lost
            request = self._take(command, newest, None)
            if frame.direction == "!":
                self.motor_rejections += 1
            else:
                self.motor_acks += 1
            if request is not None and request.burst == burst.number:
                burst.replies[command] = frame  # set_motors() waits for its own ack
            return  # an ack without a request answers a command sent while resynchronising
        request = self._take(command, newest, burst)
        if request is None:
            self.unexpected_replies += 1
            burst.unmatched += 1
            return
        if frame.direction == "!":
            self.error_replies[command] = self.error_replies.get(command, 0) + 1
        if request.burst != burst.number:
            self.late_replies += 1
            burst.late += 1
            return
        burst.replies[command] = frame

    def _take(self, command: int, newest: int, overtaking: Burst | None) -> Outstanding | None:
        request, lost = take_reply(self._outstanding, command, newest, overtaking is not None)
        if overtaking is not None:
            self.lost_requests += lost
            overtaking.lost += lost
        return request

    def send_motors(self, motors_us: Iterable[int]) -> None:
        """Write MSP_SET_MOTOR without waiting: the acknowledgement is consumed by the next poll.

        A control cycle polls, computes, then commands at once, so the motors
        never wait a whole period for a decision already made. Motor commands go
        out in every state (the board's watchdog must be fed); only while the line
        is trusted are they tracked, so acks of untracked ones are merely counted.
        """
        self.link.write(encode_v2(m.MSP_SET_MOTOR, m.encode_motors(list(motors_us))))
        self.motor_commands_sent += 1
        self._acks_owed += 1
        if self.state == "up":
            self._outstanding.append(Outstanding(m.MSP_SET_MOTOR, self.clock(), self._bursts))

    def send_neutral(self) -> None:
        """Every motor to neutral (no thrust), the safe state; written at once like any motor command."""
        self.send_motors(m.NEUTRAL_MOTORS_US)

    # ---- one control cycle ----
    def poll(self, with_battery: bool = False) -> Telemetry:
        """One control cycle's telemetry: rangefinder, attitude, gyro, flow (and the battery when asked).

        Only replies to this cycle's burst are used and ``t`` is the burst's write time. While
        stalled or resynchronising it returns at once with no fields.
        """
        now = self.clock()
        if not self._settled(now):
            return Telemetry(t=now)
        burst = self._exchange(self._poll_requests(with_battery))
        if not self._judge(burst):
            return Telemetry(t=burst.t)
        telemetry = self._telemetry(burst.replies, burst.t)
        if burst.replies:
            self.last_reply_t, self.telemetry_t = self.clock(), burst.t
        return telemetry

    def _poll_requests(self, with_battery: bool) -> _Requests:
        """This burst's telemetry requests, the rangefinder's moved one place on from burst to burst.

        The board answers in any order we ask; varying it is what lets a misalignment show.
        Should a stray frame make every reply pass for the next burst's, the next burst asks in
        another order, so its replies overtake or match nothing and the client resynchronises,
        instead of flying on telemetry one burst old for as long as the shift lasts. Only the
        rangefinder moves: the others keep their order, which keeps the simulated board's noise
        draws (attitude, then gyro) and so every simulated flight as it was.
        """
        slots = len(POLL_COMMANDS) + (1 if with_battery else 0)  # where the rangefinder can go
        return _poll_burst((self._bursts + 1) % slots, with_battery)

    def _judge(self, burst: Burst) -> bool:
        """After a burst: a silent board is stalled; a backlog, repeated stale bytes or a stray reply mean resync.

        Returns whether the burst's replies may be used: not if it ends in a resync, nor if one
        of its replies overtook a request. Either the board dropped that request, or the
        client's picture of the line is off by one (a stray frame, a torn one); only in the first
        case are the replies what they seem, and nothing tells the two apart.

        Late replies and overtaken requests count as stale bytes do: now and then they are
        allowed (a busy board may drop a request), but in a row they mean a board lagging past
        the timeout or an alignment that keeps slipping, which only a quiet line sorts out.
        """
        self._silent_bursts = 0 if burst.heard else self._silent_bursts + 1
        self._stale_run = self._stale_run + 1 if burst.disordered else 0
        if self._silent_bursts >= self.stall_bursts:
            self._stall()
        elif burst.unmatched or self._stale_run >= self.stale_bursts or len(self._outstanding) > self.max_outstanding:
            self._resync(self.clock())
            return False
        return not burst.lost

    def _stall(self) -> None:
        """Nothing comes back: stop tracking (everything outstanding is doubtful now) and probe until it does."""
        self.stalls += 1
        self.state = "stalled"
        self._forget()

    def _resync(self, now: float) -> None:
        """Discard the input and forget every outstanding request; telemetry waits until the line is quiet."""
        self.resyncs += 1
        self.state = "resyncing"
        self._discard_waiting()
        self._forget()
        self._noise_t = now
        self._acks_owed_at_resync, self._acks_since_resync = self._acks_owed, 0
        self._motors_at_resync = self.motor_commands_sent

    def _forget(self) -> None:
        self.parser.abandon()
        self._outstanding.clear()
        self._silent_bursts = self._stale_run = 0

    def _wait_settled(self) -> bool:
        """Block (request() only; the control loop never waits) until replies can be trusted, or give up."""
        deadline = self.clock() + self.quiet_s + self.timeout_s
        while not self._settled(self.clock(), block=True):
            if self.clock() >= deadline:
                return False
        return True

    def _settled(self, now: float, block: bool = False) -> bool:
        """Listen while stalled or resynchronising; True once replies can be trusted again (at once when up)."""
        if self.state == "up":
            return True
        heard, noisy = self._discard_waiting(block)
        if self.state == "stalled":
            if not heard:
                self.link.write(encode_v2(PROBE_COMMAND))
                self._replies_owed += 1
                return False
            self._resync(now)  # the board is back, perhaps answering the stall's backlog
        elif noisy:
            self._noise_t = now
        if now - self._noise_t < self.quiet_s or not self._backlog_answered():
            return False
        self.state = "up"
        return True

    def _backlog_answered(self) -> bool:
        """Whether a reply to a request written before the resync can still come.

        Replies come in order: not once every request has been answered, nor once a motor
        command written after the resync began has been acknowledged. Without motor commands
        there is no such proof and the quiet spell has to do.
        """
        return (
            self._replies_owed == 0
            or self._acks_since_resync > self._acks_owed_at_resync
            or self.motor_commands_sent == self._motors_at_resync
        )

    def _discard_waiting(self, block: bool = False) -> tuple[bool, bool]:
        """Read and drop what is waiting (or, blocking, what comes within a read timeout), all counted as stale.

        Returns (anything heard, anything besides motor acks).
        """
        data = self._read_some() if block else self._read_waiting()
        if not data:
            return False, False
        self.stale_bytes += len(data)
        counters = self.parser.counters
        errors_before = counters.garbage_bytes + counters.bad_checksums + counters.oversized
        frames = self._frames(data)
        errors_after = counters.garbage_bytes + counters.bad_checksums + counters.oversized
        return True, errors_after > errors_before or not all(is_ack(f) for f in frames)

    def _read_waiting(self) -> bytes:
        """What the link already holds, without blocking (a read of nothing would wait for its timeout)."""
        waiting = self.link.in_waiting
        return self.link.read(waiting) if waiting else b""

    def _telemetry(self, replies: dict[int, MspFrame], t: float) -> Telemetry:
        telemetry, bad = decode_telemetry(replies, t)
        self.bad_payloads += bad
        return telemetry

    def telemetry_age_s(self) -> float | None:
        """How old the newest in-time telemetry is (from its burst's write time); None before the first."""
        return None if self.telemetry_t is None else self.clock() - self.telemetry_t

    def _oldest_outstanding_s(self) -> float | None:
        """How long the oldest tracked request has waited: how far behind a lagging board is.

        Read by health() on the event loop while the serial thread polls, which may take the last request
        between a check and a read: so one read, and an empty FIFO found there is none.
        """
        try:
            oldest = self._outstanding[0]
        except IndexError:
            return None
        return self.clock() - oldest.written_t

    def health(self) -> dict[str, object]:
        return {
            **self.parser.counters.as_dict(),
            "state": self.state,
            "stalled": self.stalled,
            "timeouts": self.timeouts,
            "unexpected_replies": self.unexpected_replies,
            "error_replies_by_command": dict(self.error_replies),
            "bad_payloads": self.bad_payloads,
            "motor_commands_sent": self.motor_commands_sent,
            "motor_acks": self.motor_acks,
            "motor_rejections": self.motor_rejections,
            "late_replies": self.late_replies,
            "lost_requests": self.lost_requests,
            "stale_bytes": self.stale_bytes,
            "stalls": self.stalls,
            "resyncs": self.resyncs,
            "outstanding": len(self._outstanding),
            "oldest_outstanding_s": self._oldest_outstanding_s(),
            "last_reply_t": self.last_reply_t,
            "telemetry_age_s": self.telemetry_age_s(),
        }
