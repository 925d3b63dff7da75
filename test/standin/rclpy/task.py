"""rclpy.task: Future and Task.

A Task runs a callback; when the callback is a coroutine function (async def) the Task steps the
coroutine each time the executor runs it, and the coroutine may `await` any Future: the task then
sleeps until that Future is done (set_result from another callback, a service response, ...).
"""
from __future__ import annotations

import inspect
from typing import Any, Callable


class Future:
    def __init__(self, *, executor=None) -> None:
        self._state = "PENDING"
        self._result = None
        self._exception: BaseException | None = None
        self._callbacks: list[Callable] = []
        self._executor = executor

    def __await__(self):
        # Yield ourselves so the stand-in executor knows what the task waits for.
        while not self.done():
            yield self
        return self.result()

    def cancel(self) -> None:
        if not self.done():
            self._state = "CANCELLED"
            self._invoke_done_callbacks()

    def cancelled(self) -> bool:
        return self._state == "CANCELLED"

    def done(self) -> bool:
        return self._state in ("FINISHED", "CANCELLED")

    def result(self) -> Any:
        if self._exception is not None:
            raise self._exception
        return self._result

    def exception(self) -> BaseException | None:
        return self._exception

    def set_result(self, result: Any) -> None:
        self._result = result
        self._state = "FINISHED"
        self._invoke_done_callbacks()

    def set_exception(self, exception: BaseException) -> None:
        self._exception = exception
        self._state = "FINISHED"
        self._invoke_done_callbacks()

    def _invoke_done_callbacks(self) -> None:
        callbacks, self._callbacks = self._callbacks, []
        for callback in callbacks:
            callback(self)

    def add_done_callback(self, callback: Callable[["Future"], None]) -> None:
        if self.done():
            callback(self)
        else:
            self._callbacks.append(callback)

    def remove_done_callback(self, callback) -> bool:
        try:
            self._callbacks.remove(callback)
            return True
        except ValueError:
            return False


class Task(Future):
    def __init__(self, handler: Callable, args=None, kwargs=None, executor=None) -> None:
        super().__init__(executor=executor)
        self._handler = handler
        self._args = args or ()
        self._kwargs = kwargs or {}
        self._coro = handler if inspect.iscoroutine(handler) else None
        self._executing = False
        self._waiting_on: Future | None = None

    def executing(self) -> bool:
        return self._executing

    def ready(self) -> bool:
        """True when running the task would make progress."""
        if self.done() or self._executing:
            return False
        return self._waiting_on is None or self._waiting_on.done()

    def __call__(self) -> None:
        if self.done() or self._executing:
            return
        self._executing = True
        try:
            if self._coro is None:
                result = self._handler(*self._args, **self._kwargs)
                if inspect.iscoroutine(result):
                    self._coro = result
                else:
                    self.set_result(result)
                    return
            self._step()
        except BaseException as exc:  # noqa: BLE001 - stored like rclpy, re-raised by the executor
            self.set_exception(exc)
        finally:
            self._executing = False

    def _step(self) -> None:
        self._waiting_on = None
        try:
            awaited = self._coro.send(None)
        except StopIteration as stop:
            self.set_result(stop.value)
            return
        if isinstance(awaited, Future):
            self._waiting_on = awaited
