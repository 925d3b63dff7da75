"""rclpy.callback_groups (the stand-in runs everything on one thread, so groups only record membership)."""
from __future__ import annotations


class CallbackGroup:
    def __init__(self) -> None:
        self.entities: list = []

    def add_entity(self, entity) -> None:
        self.entities.append(entity)

    def has_entity(self, entity) -> bool:
        return entity in self.entities

    def can_execute(self, entity) -> bool:
        return True

    def beginning_execution(self, entity) -> bool:
        return True

    def ending_execution(self, entity) -> None:
        pass


class ReentrantCallbackGroup(CallbackGroup):
    pass


class MutuallyExclusiveCallbackGroup(CallbackGroup):
    pass
