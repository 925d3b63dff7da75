"""Why an action server of the hand refuses a goal, in the words the goal's result carries.

Every action server of the hand accepts each goal it is sent and, when it cannot carry it out,
aborts it at once with `<code>: <why>` in the result's text field (Grasp `reason`, Manipulate
`stop_reason`, MoveMotors `reason`; GripperCommand has no text field: the manipulation node logs
it and puts it on /diagnostics). A manipulation goal whose MoveMotors goal the motor driver refuses
ends with the driver's refusal as its reason. A rejected
goal would tell its client only "Goal was rejected"; an aborted one shows the reason in
`ros2 action send_goal`'s output. The code says what the client can do about it:
- `invalid`: the goal can never run as sent (a value beyond a limit, an unknown name): change it;
- `not_ready`: the hand cannot run it yet (a stream it needs missing or stale, the motor driver or
  its bus down, the motors homing): send it again later;
- `busy`: another goal runs on the same node: wait for its end or cancel it;
- `not_homed`: a motor's zero is not known since its servo powered up (the motor driver): home the
  motors (the HomeMotors action, or `home:=true` at launch), then send it again.
Nodes may add codes of their own (the manipulation node's `no_contact`).
"""
from __future__ import annotations

from dataclasses import dataclass

INVALID = "invalid"
NOT_READY = "not_ready"
BUSY = "busy"
NOT_HOMED = "not_homed"
RETRY_LATER = (NOT_READY, BUSY)  # the same goal may run when sent again


@dataclass(frozen=True)
class Refusal:
    code: str
    why: str

    def __str__(self) -> str:
        return f"{self.code}: {self.why}"


def refusal_code(reason: str) -> str | None:
    """The code of a result's reason text that is a refusal of a known code, else None."""
    code, sep, _ = reason.partition(": ")
    return code if sep and code in (INVALID, NOT_READY, BUSY, NOT_HOMED) else None
