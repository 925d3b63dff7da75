"""Sensor watchdog: data older than `stale_ns` (100 ms) stops the motors (docs/safety.md).

Two clocks, two questions:
- Age, by header stamps. A stream's age is the latest /joint_states header stamp minus the stream's
  latest header stamp. /joint_states comes from the motor driver at 100 Hz on the same ROS time
  base as the taxels, so this works unchanged with `ros2 bag play`, use_sim_time and sim, and
  catches a sensor hub that still talks but delivers old samples.
- Silence, by receipt time on the node's clock: a stream (taxels, wrenches, /joint_states itself)
  that has not delivered anything for `stale_ns` is stale even when no reference moves, e.g. when
  the hub is unplugged or the motor driver is gone.
A goal is granted `stale_ns` from its start before a stream that never arrived counts as silent.

A check that comes more than half of `stale_ns` after the previous one was held up with the node
(its process got no CPU): messages that arrived meanwhile still wait in the node's queues, behind
this check, so their streams only look silent. Silence is then counted from the end of the hold-up,
as from a goal's start. Ages by stamp are judged as always, except for a stream that has not
delivered since the hold-up ended: its newest stamp is from before the hold-up, and against a
/joint_states taken first after it that reads as old as the hold-up was long (a loaded pass ended a
teleop goal `taxels/thumb 405 ms older than /joint_states` so, the motor driver's lease having
expired 7 ms before). Such a stream is judged by silence alone until it delivers or its grace ends.
Only an isolated hold-up is forgiven: a check held up right after another one judges silence by
receipt alone, so a node starved for good still stops the motors (and the motor driver's goal lease
stops them in any case).

`fresh` asks the same two questions before a goal is accepted, without that grace: a goal is only
accepted once every stream it needs (and /joint_states) is flowing.

A goal kind's input (a glove's targets) is asked the same two questions with its own timeout
(`check_input`), except that a goal may wait for it: until it comes, nothing is stale. Before a goal
is admitted its input is asked them too (`input_fresh`): targets that came and are already stale
refuse the goal, so that the goal never steps on them.

A sample whose own stamp is refused on arrival (prisma_common.sample_stamps: stamped 0, ahead of the
node's clock, too old; judged by the core) does not count as delivered (`refuse`): while its stream's
latest sample is refused, `fresh`, `check` and `check_input` answer with the refusal's line (it names
the stream and the fix), which says more than the silence it would otherwise come to.
"""
from __future__ import annotations

from dataclasses import dataclass

STALE_NS_DEFAULT = 100_000_000
JOINT_STATES = "/joint_states"  # the time base's name among the streams


@dataclass
class _Stream:
    stamp_ns: int
    receipt_ns: int


class SensorWatchdog:
    def __init__(self, stale_ns: int = STALE_NS_DEFAULT) -> None:
        if stale_ns <= 0:
            raise ValueError(f"stale timeout {stale_ns} ns must be > 0")
        self.stale_ns = stale_ns
        self._streams: dict[str, _Stream] = {}
        self._reference_ns: int | None = None
        self._joint_receipt_ns: int | None = None
        self._armed_ns: int | None = None
        self._last_check_ns: int | None = None
        self._resumed_ns: int | None = None  # end of the last forgiven hold-up
        self._held_up = False  # the previous check was held up
        self._refused: dict[str, tuple[str, int]] = {}  # stream -> (why its latest sample was refused, receipt)

    def _note_check(self, now_ns: int) -> None:
        held_up = self._last_check_ns is not None and now_ns - self._last_check_ns > self.stale_ns // 2
        if held_up:  # forgiven once; held up again right after, silence counts by receipt alone
            self._resumed_ns = None if self._held_up else now_ns
        self._held_up = held_up
        self._last_check_ns = now_ns

    def arm(self, now_ns: int) -> None:
        """A goal starts: streams get `stale_ns` from now to (re)appear."""
        self._armed_ns = now_ns
        self._last_check_ns, self._resumed_ns, self._held_up = now_ns, None, False

    def disarm(self) -> None:
        self._armed_ns = None

    def sample(self, stream: str, stamp_ns: int, receipt_ns: int) -> None:
        # the age of what just arrived counts, even when an earlier message was newer: a sample
        # delivered 150 ms late is stale data
        self._streams[stream] = _Stream(stamp_ns, receipt_ns)
        self._refused.pop(stream, None)

    def reference(self, stamp_ns: int, receipt_ns: int) -> None:
        """A /joint_states header stamp: the time base ages are measured against."""
        if self._reference_ns is None or stamp_ns > self._reference_ns:
            self._reference_ns = stamp_ns
        self._joint_receipt_ns = receipt_ns
        self._refused.pop(JOINT_STATES, None)

    def refuse(self, stream: str, why: str, receipt_ns: int) -> None:
        """A sample of `stream` (JOINT_STATES for /joint_states) arrived whose stamp is refused: `why`."""
        self._refused[stream] = (why, receipt_ns)

    def refusal(self, stream: str, within_ns: int, now_ns: int) -> str | None:
        """Why the latest sample of `stream` was refused, when it arrived within `within_ns` of now."""
        refused = self._refused.get(stream)
        return refused[0] if refused is not None and now_ns - refused[1] <= within_ns else None

    def fresh(self, streams: tuple[str, ...] | list[str], now_ns: int) -> str | None:
        """None when /joint_states and every named stream delivered within `stale_ns` (by receipt)
        and no stream is older than `stale_ns` against /joint_states; else why not, naming the stream."""
        refused = self.refusal(JOINT_STATES, self.stale_ns, now_ns)
        if refused is not None:
            return refused
        if self._joint_receipt_ns is None:
            return "no /joint_states received yet"
        if now_ns - self._joint_receipt_ns > self.stale_ns:
            return f"/joint_states silent for {(now_ns - self._joint_receipt_ns) / 1e6:.0f} ms"
        for name in streams:
            refused = self.refusal(name, self.stale_ns, now_ns)
            if refused is not None:
                return refused
            s = self._streams.get(name)
            if s is None:
                return f"no {name} received yet"
            if now_ns - s.receipt_ns > self.stale_ns:
                return f"{name} silent for {(now_ns - s.receipt_ns) / 1e6:.0f} ms"
            if self._reference_ns is not None and self._reference_ns - s.stamp_ns > self.stale_ns:
                return f"{name} {(self._reference_ns - s.stamp_ns) / 1e6:.0f} ms older than /joint_states"
        return None

    def check(self, streams: tuple[str, ...] | list[str], now_ns: int) -> str | None:
        """None when every named stream is fresh, else a description of the first stale one."""
        if self._armed_ns is None:
            return None
        self._note_check(now_ns)
        grace_from = max(self._armed_ns, self._resumed_ns or self._armed_ns)
        joint_seen = self._joint_receipt_ns if self._joint_receipt_ns is not None else grace_from
        refused = self.refusal(JOINT_STATES, self.stale_ns, now_ns)
        if refused is not None:
            return refused
        if now_ns - max(joint_seen, grace_from) > self.stale_ns:
            return f"/joint_states silent for {(now_ns - joint_seen) / 1e6:.0f} ms"
        for name in streams:
            refused = self.refusal(name, self.stale_ns, now_ns)
            if refused is not None:
                return refused
            s = self._streams.get(name)
            receipt = s.receipt_ns if s else None
            if now_ns - max(receipt if receipt is not None else grace_from, grace_from) > self.stale_ns:
                silent = (now_ns - receipt) / 1e6 if receipt is not None else (now_ns - grace_from) / 1e6
                return f"{name} silent for {silent:.0f} ms"
            if s and self._reference_ns is not None and not self._awaited_after_hold_up(s):
                age = self._reference_ns - s.stamp_ns
                if age > self.stale_ns:
                    return f"{name} {age / 1e6:.0f} ms older than /joint_states"
        return None

    def _awaited_after_hold_up(self, s: _Stream) -> bool:
        """The stream has not delivered since a forgiven hold-up ended: its newest stamp dates from
        before the hold-up, so its age says how long the hold-up was. (Its grace is the silence check's,
        which runs first: past the timeout from the resume the stream is already silent.)"""
        return self._resumed_ns is not None and s.receipt_ns < self._resumed_ns

    def oldest_receipt(self, streams: tuple[str, ...] | list[str]) -> int | None:
        """When the least recent of /joint_states and `streams` last arrived: a decision taken now rests
        on nothing newer (None: one of them never came)."""
        receipts = [self._joint_receipt_ns] + [s.receipt_ns if (s := self._streams.get(n)) else None
                                               for n in streams]
        return None if any(r is None for r in receipts) else min(r for r in receipts if r is not None)

    def arrived(self, stream: str, timeout_ns: int) -> bool:
        """A goal kind's input came for the running goal: received since `timeout_ns` before its start
        (an older value is not one to follow)."""
        s = self._streams.get(stream)
        return self._armed_ns is not None and s is not None and s.receipt_ns >= self._armed_ns - timeout_ns

    def check_input(self, stream: str, timeout_ns: int, now_ns: int, label: str | None = None) -> str | None:
        """A goal kind's input during a goal, after `check` of the same tick: None while it has not
        come since `timeout_ns` before the goal's start (the goal waits for it), else as `check` with
        `timeout_ns`: silent by receipt (counted from the end of a forgiven hold-up), or older than
        /joint_states by stamp (once it delivered after a forgiven hold-up). The description names it
        `label` (its topic), else `stream`."""
        refused = self._refused.get(stream)
        if refused is not None and self._armed_ns is not None and refused[1] >= self._armed_ns - timeout_ns:
            return refused[0]
        s = self._streams.get(stream)
        if s is None or not self.arrived(stream, timeout_ns):
            return None
        name = label or stream
        if now_ns - max(s.receipt_ns, self._resumed_ns or s.receipt_ns) > timeout_ns:
            return f"{name} silent for {(now_ns - s.receipt_ns) / 1e6:.0f} ms"
        if (self._reference_ns is not None and self._reference_ns - s.stamp_ns > timeout_ns
                and not self._awaited_after_hold_up(s)):
            return f"{name} {(self._reference_ns - s.stamp_ns) / 1e6:.0f} ms older than /joint_states"
        return None

    def input_fresh(self, stream: str, timeout_ns: int, now_ns: int, label: str | None = None) -> str | None:
        """Before a goal is admitted: None unless the goal kind's input came within `timeout_ns` and is
        already unusable (its latest sample refused, or older than /joint_states by more than
        `timeout_ns`); then why, naming it `label` (its topic), else `stream`. An input that has not
        come is not a reason to refuse: the goal waits for it."""
        refused = self.refusal(stream, timeout_ns, now_ns)
        if refused is not None:
            return refused
        s = self._streams.get(stream)
        if s is None or now_ns - s.receipt_ns > timeout_ns or self._reference_ns is None:
            return None
        age = self._reference_ns - s.stamp_ns
        return f"{label or stream} {age / 1e6:.0f} ms older than /joint_states" if age > timeout_ns else None
