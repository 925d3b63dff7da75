"""Stand-in for the compiled rclpy extension: only its error type."""


class RCLError(RuntimeError):
    """Raised where rcl would return an error (e.g. an invalid goal state transition)."""
