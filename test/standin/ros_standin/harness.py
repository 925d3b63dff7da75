"""The `ros` test fixture's object: one fresh ROS context per test, spun deterministically.

    def test_x(ros):
        node = MyNode()                       # every node created in the test joins ros.executor
        seen = ros.collect(TaxelArray, "/prisma/index/taxels")
        ros.advance(0.05)                     # 50 ms of test time: timers fire in deadline order,
                                              # every message/service/action step is delivered
        assert len(seen) == 5

Nothing happens between calls: time stands still until `advance`, and callbacks run only inside
`process`, `advance`, `spin_until` (or the rclpy spin functions).
"""
from __future__ import annotations

from typing import Any, Callable

from . import clock as _clock
from . import records as _records
from .arguments import ALL_NODES, read_params_file

_MAX_CALLBACKS = 1_000_000


class RosHarness:
    """Stand-in implementation of the fixture (the real-rclpy one lives in test/conftest.py)."""

    uses_standin = True

    def __init__(self, args: list[str] | None = None) -> None:
        import rclpy
        import rclpy.logging
        from rclpy.executors import SingleThreadedExecutor

        _clock.TEST_CLOCK.reset()
        _records.clear()
        rclpy.logging._reset()
        rclpy._reset_global_executor()
        rclpy.try_shutdown()
        rclpy.init(args=args)
        self.rclpy = rclpy
        self.context = rclpy.get_default_context()
        self.executor = SingleThreadedExecutor()
        self.context.graph.node_created_hooks.append(self.executor.add_node)
        self._probe = None

    # -- time ---------------------------------------------------------------------------------

    @property
    def clock(self) -> _clock.TestClock:
        return _clock.TEST_CLOCK

    def now_ns(self) -> int:
        return _clock.TEST_CLOCK.now_ns

    # -- nodes and parameters -------------------------------------------------------------------

    def add(self, node):
        """Make sure `node` is spun by the fixture (automatic in the stand-in); returns it."""
        self.executor.add_node(node)
        return node

    def override(self, node: str = ALL_NODES, **params: Any) -> None:
        """Parameter overrides for nodes created afterwards, like `--ros-args -p name:=value`
        (`node` narrows them to a node name, e.g. 'tactile_driver', as in a params file)."""
        self.context.parameter_overrides.append((node, dict(params)))

    def params_file(self, path) -> None:
        """Overrides from a ros__parameters YAML file (e.g. config/<node>.yaml), like --params-file."""
        self.context.parameter_overrides.extend(read_params_file(path))

    # -- running callbacks ------------------------------------------------------------------------

    def process(self, max_callbacks: int = _MAX_CALLBACKS) -> int:
        """Run every ready callback (due timers, queued messages, service/action steps, resumed
        tasks) until nothing is ready; test time does not move. Returns the number run."""
        count = 0
        while self.executor._step():
            count += 1
            if count >= max_callbacks:
                raise RuntimeError(f"still busy after {count} callbacks (zero-period timer or a feedback loop?)")
        return count

    def advance(self, seconds: float) -> int:
        """Let `seconds` of test time pass: stop at each timer deadline in order, fire what is due
        and process everything it triggers, then end exactly `seconds` later. Returns callbacks run."""
        target = _clock.TEST_CLOCK.now_ns + int(round(seconds * 1e9))
        count = self.process()
        while True:
            deadline = self.executor.next_timer_deadline_ns()
            if deadline is None or deadline > target:
                break
            _clock.TEST_CLOCK.set_ns(max(deadline, _clock.TEST_CLOCK.now_ns))
            count += self.process()
        _clock.TEST_CLOCK.set_ns(max(target, _clock.TEST_CLOCK.now_ns))
        return count + self.process()

    def spin_until(self, condition, timeout_sec: float = 10.0, step_sec: float | None = None) -> bool:
        """Process and advance test time (to each timer deadline, or by `step_sec`) until
        `condition` (a Future, or a callable returning truthy) holds or `timeout_sec` of test time
        passed. Returns whether it holds."""
        done: Callable[[], bool] = condition.done if hasattr(condition, "done") else condition
        end = _clock.TEST_CLOCK.now_ns + int(round(timeout_sec * 1e9))
        self.process()
        while not done():
            now = _clock.TEST_CLOCK.now_ns
            if now >= end:
                return False
            deadline = self.executor.next_timer_deadline_ns()
            if step_sec is not None:
                deadline = min(deadline or end, now + int(round(step_sec * 1e9)))
            if deadline is None:
                return bool(done())
            _clock.TEST_CLOCK.set_ns(min(max(deadline, now), end))
            self.process()
        return True

    # -- probes -----------------------------------------------------------------------------------

    @property
    def probe(self):
        """A node of the test itself, for publishing, subscribing and calling."""
        if self._probe is None:
            self._probe = self.rclpy.create_node("test_probe")
            self.add(self._probe)
        return self._probe

    def collect(self, msg_type, topic: str, qos_profile=10) -> list:
        """A list that receives every message on `topic` from now on (when processed)."""
        received: list = []
        self.probe.create_subscription(msg_type, topic, received.append, qos_profile)
        return received

    def publisher(self, msg_type, topic: str, qos_profile=10):
        return self.probe.create_publisher(msg_type, topic, qos_profile)

    def publish(self, topic: str, msg, qos_profile=10) -> None:
        """Publish `msg` from the probe node (a publisher per topic and type is kept)."""
        from .messages import get_class

        msg_type = get_class(msg.__msgtype__)
        key = (topic, msg_type)
        publishers = self.__dict__.setdefault("_publishers", {})
        if key not in publishers:
            publishers[key] = self.publisher(msg_type, topic, qos_profile)
        publishers[key].publish(msg)

    def call(self, srv_type, name: str, request, timeout_sec: float = 10.0):
        """Call a service from the probe node and return the response (None if none came)."""
        key = (name, srv_type)
        clients = self.__dict__.setdefault("_clients", {})
        if key not in clients:
            clients[key] = self.probe.create_client(srv_type, name)
        future = clients[key].call_async(request)
        self.spin_until(future, timeout_sec)
        return future.result() if future.done() else None

    def action_client(self, action_type, name: str):
        from rclpy.action import ActionClient

        return ActionClient(self.probe, action_type, name)

    # -- logs -------------------------------------------------------------------------------------

    def logs(self, severity: str | None = None, name: str | None = None, contains: str | None = None):
        """Log records so far, optionally filtered by severity ('INFO', 'WARN', 'ERROR', ...),
        logger name (the node name) and a substring of the message."""
        out = []
        for record in _records.RECORDS:
            if severity is not None and record.severity != severity.upper().replace("WARNING", "WARN"):
                continue
            if name is not None and record.name != name:
                continue
            if contains is not None and contains not in record.message:
                continue
            out.append(record)
        return out

    # -- teardown -----------------------------------------------------------------------------------

    def shutdown(self) -> None:
        self.executor.shutdown()
        self.rclpy.try_shutdown()
        self.rclpy._reset_global_executor()
