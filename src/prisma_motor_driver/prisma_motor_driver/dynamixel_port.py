"""The serial port dynamixel-sdk talks through, made to wait for bytes instead of polling for them."""
from __future__ import annotations

import dynamixel_sdk as sdk

# How long one read of the port waits for the status packet's bytes (the SDK's packet timeout,
# ~34 ms, still bounds the whole wait).
READ_WAIT_S = 0.002


class WaitingPortHandler(sdk.PortHandler):
    """dynamixel-sdk's PortHandler with reads that wait up to READ_WAIT_S for bytes.

    The SDK opens the port non-blocking and polls it in a loop until the status packet is complete:
    at the driver's real-time priority that loop holds a core for the whole transaction, and
    whatever else needs it (the servos' emulator, the tactile driver) waits. A read that sleeps in
    select until the bytes come costs nothing while the servo answers.
    """

    def setupPort(self, cflag_baud: int) -> bool:  # noqa: N802 - the SDK's name
        opened = super().setupPort(cflag_baud)
        self.ser.timeout = READ_WAIT_S
        return opened
