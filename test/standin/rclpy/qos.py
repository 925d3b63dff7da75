"""rclpy.qos: QoSProfile, the policies and the preset profiles (values as in Jazzy).

The stand-in uses reliability and durability to decide whether a publisher reaches a
subscription, as DDS does: a RELIABLE subscription does not match a BEST_EFFORT publisher, a
TRANSIENT_LOCAL subscription does not match a VOLATILE publisher. KEEP_LAST depth bounds the
subscription's queue of undelivered messages; a TRANSIENT_LOCAL publisher replays its last
`depth` messages to a late TRANSIENT_LOCAL subscription.
"""
from __future__ import annotations

from enum import IntEnum


class InvalidQoSProfileException(Exception):
    def __init__(self, *args):
        Exception.__init__(self, "Invalid QoSProfile", *args)


class HistoryPolicy(IntEnum):
    SYSTEM_DEFAULT = 0
    KEEP_LAST = 1
    KEEP_ALL = 2
    UNKNOWN = 3


class ReliabilityPolicy(IntEnum):
    SYSTEM_DEFAULT = 0
    RELIABLE = 1
    BEST_EFFORT = 2
    UNKNOWN = 3
    BEST_AVAILABLE = 4


class DurabilityPolicy(IntEnum):
    SYSTEM_DEFAULT = 0
    TRANSIENT_LOCAL = 1
    VOLATILE = 2
    UNKNOWN = 3
    BEST_AVAILABLE = 4


class LivelinessPolicy(IntEnum):
    SYSTEM_DEFAULT = 0
    AUTOMATIC = 1
    MANUAL_BY_TOPIC = 3
    UNKNOWN = 4
    BEST_AVAILABLE = 5


# Old names still used in examples.
QoSHistoryPolicy = HistoryPolicy
QoSReliabilityPolicy = ReliabilityPolicy
QoSDurabilityPolicy = DurabilityPolicy
QoSLivelinessPolicy = LivelinessPolicy


class QoSProfile:
    def __init__(self, **kwargs) -> None:
        if "history" not in kwargs and "depth" not in kwargs:
            raise InvalidQoSProfileException("History and/or depth settings are required.")
        self.history = HistoryPolicy(kwargs.get("history", HistoryPolicy.KEEP_LAST))
        self.depth = int(kwargs.get("depth", 0))
        if self.history == HistoryPolicy.KEEP_LAST and self.depth == 0 and "depth" in kwargs:
            raise InvalidQoSProfileException("A depth of zero is invalid with KEEP_LAST history")
        self.reliability = ReliabilityPolicy(kwargs.get("reliability", ReliabilityPolicy.RELIABLE))
        self.durability = DurabilityPolicy(kwargs.get("durability", DurabilityPolicy.VOLATILE))
        self.liveliness = LivelinessPolicy(kwargs.get("liveliness", LivelinessPolicy.SYSTEM_DEFAULT))
        self.lifespan = kwargs.get("lifespan")
        self.deadline = kwargs.get("deadline")
        self.liveliness_lease_duration = kwargs.get("liveliness_lease_duration")
        self.avoid_ros_namespace_conventions = bool(kwargs.get("avoid_ros_namespace_conventions", False))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, QoSProfile):
            return NotImplemented
        return all(getattr(self, k) == getattr(other, k) for k in ("history", "depth", "reliability", "durability"))

    def __repr__(self) -> str:
        return (f"QoSProfile(history={self.history.name}, depth={self.depth}, "
                f"reliability={self.reliability.name}, durability={self.durability.name})")


def as_profile(qos_profile) -> QoSProfile:
    """An int is a KEEP_LAST depth, as in create_publisher(msg_type, topic, 10)."""
    if isinstance(qos_profile, QoSProfile):
        return qos_profile
    if isinstance(qos_profile, int) and not isinstance(qos_profile, bool):
        if qos_profile < 0:
            raise ValueError("history depth must be greater than or equal to zero")
        return QoSProfile(depth=qos_profile)
    raise TypeError("Expected QoSProfile or int, but received {!r}".format(type(qos_profile)))


def compatible(publisher: QoSProfile, subscription: QoSProfile) -> bool:
    if (subscription.reliability == ReliabilityPolicy.RELIABLE
            and publisher.reliability == ReliabilityPolicy.BEST_EFFORT):
        return False
    if (subscription.durability == DurabilityPolicy.TRANSIENT_LOCAL
            and publisher.durability == DurabilityPolicy.VOLATILE):
        return False
    return True


qos_profile_sensor_data = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=5,
    reliability=ReliabilityPolicy.BEST_EFFORT, durability=DurabilityPolicy.VOLATILE)
qos_profile_system_default = QoSProfile(
    history=HistoryPolicy.SYSTEM_DEFAULT, depth=0,
    reliability=ReliabilityPolicy.SYSTEM_DEFAULT, durability=DurabilityPolicy.SYSTEM_DEFAULT)
qos_profile_services_default = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=10,
    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
qos_profile_parameters = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1000,
    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
qos_profile_parameter_events = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1000,
    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
qos_profile_action_status_default = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1,
    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


class QoSPresetProfiles:
    SENSOR_DATA = qos_profile_sensor_data
    SYSTEM_DEFAULT = qos_profile_system_default
    SERVICES_DEFAULT = qos_profile_services_default
    PARAMETERS = qos_profile_parameters
    PARAMETER_EVENTS = qos_profile_parameter_events
    ACTION_STATUS_DEFAULT = qos_profile_action_status_default
