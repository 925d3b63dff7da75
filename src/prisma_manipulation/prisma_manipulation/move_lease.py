"""The MoveMotors lease: every velocity goal this node sends the motor driver carries a short timeout
(`MOVE_LEASE_S`) and, while the controller keeps the same command, is re-sent every `MOVE_REFRESH_S`.
A node that dies or hangs stops re-sending; the driver's goal times out and it stops the motors.

Each goal is stamped with when its data arrived (`SendMove`), so a renewal decided on data the
watchdog still calls fresh, held back by a dropped link and delivered when it comes back, is refused
by the driver as expired instead of starting the motors again; the watchdog's window stays below the
lease (node_config.py) to keep that bound short.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

# MoveMotors goals last this long on the motor driver unless re-sent: the motors stop within it (+ one
# driver tick) when this node dies. Re-sent every MOVE_REFRESH_S, so two refreshes may be late (a busy
# executor) before the motors stop under a live controller.
MOVE_LEASE_S = 0.3
MOVE_REFRESH_S = 0.1
# A goal's stamp counts the age of its data up to this much: what is left of its lease outlasts a
# refresh period and 50 ms of transit and a late executor, so that old (but not stale) data shortens
# the lease without letting it end between two refreshes of a live controller.
MAX_DATA_AGE_S = MOVE_LEASE_S - MOVE_REFRESH_S - 0.05


@dataclass(frozen=True)
class SendMove:
    """A MoveMotors velocity goal. Its stamp, from which the driver counts its timeout, is when the
    oldest data the command rests on arrived (at most MAX_DATA_AGE_S before it is sent), not when
    it is sent: a renewal held back by a dropped link, or sent on data a link stopped delivering,
    lasts no longer than a lease past that data (or, for data older than MAX_DATA_AGE_S, a refresh
    period and 50 ms past its sending)."""

    velocities_rpm: dict[str, float]
    timeout_s: float
    stamp_ns: int


@dataclass(frozen=True)
class StopMotors:
    pass


class MoveLease:
    """The MoveMotors goals that carry one velocity command: sent with a `lease_s` timeout, re-sent
    every `refresh_s` while the command holds, so the motor driver stops the motors on its own when
    the sender is gone. The off-robot recorder (prisma_sim.hand_session) runs the same decisions."""

    def __init__(self, lease_s: float = MOVE_LEASE_S, refresh_s: float = MOVE_REFRESH_S,
                 max_data_age_s: float = MAX_DATA_AGE_S) -> None:
        if not 0 < refresh_s < lease_s:
            raise ValueError(f"refresh {refresh_s} s must be > 0 and below the lease {lease_s} s")
        if not 0 <= max_data_age_s <= lease_s - refresh_s:
            raise ValueError(f"max data age {max_data_age_s} s must be from 0 to the lease less a refresh "
                             f"({lease_s - refresh_s:g} s)")
        self.lease_s = lease_s
        self.refresh_ns = int(round(refresh_s * 1e9))
        self.max_data_age_ns = int(round(max_data_age_s * 1e9))
        self.velocities: dict[str, float] | None = None  # the command being kept alive, None = none
        self.sent_ns = 0

    def command(self, velocities_rpm: Mapping[str, float], now_ns: int, data_ns: int) -> SendMove | StopMotors:
        """A new command from the controller, decided on data the oldest of which arrived at `data_ns`:
        a goal for motion, a cancel for a stop."""
        if all(v == 0.0 for v in velocities_rpm.values()):
            self.velocities = None
            return StopMotors()
        self.velocities = dict(velocities_rpm)
        return self._send(self.velocities, now_ns, data_ns)

    def refresh(self, now_ns: int, data_ns: int) -> SendMove | None:
        """The same command again when the last goal is `refresh_s` old (on data from `data_ns`)."""
        if self.velocities is None or now_ns - self.sent_ns < self.refresh_ns:
            return None
        return self._send(self.velocities, now_ns, data_ns)

    def renew(self, now_ns: int, data_ns: int) -> SendMove | None:
        """The driver ended the goal by its timeout before the refresh came: send it again now."""
        return None if self.velocities is None else self._send(self.velocities, now_ns, data_ns)

    def release(self) -> None:
        """Nothing to keep alive (goal over, or the driver stopped the motors at a limit)."""
        self.velocities = None

    def _send(self, velocities: dict[str, float], now_ns: int, data_ns: int) -> SendMove:
        self.sent_ns = now_ns
        return SendMove(dict(velocities), self.lease_s, min(max(data_ns, now_ns - self.max_data_age_ns), now_ns))
