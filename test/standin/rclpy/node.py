"""rclpy.node.Node of the stand-in: Jazzy signatures over the in-memory graph of the context."""
from __future__ import annotations

import inspect
import math
import warnings
from collections import deque
from typing import Any, Callable, Iterator

from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from ros_standin import arguments as _arguments
from ros_standin import clock as _test_clock
from ros_standin import names as _names
from ros_standin.messages import convert as _convert

from . import qos as _qos
from .callback_groups import CallbackGroup, MutuallyExclusiveCallbackGroup
from .clock import Clock, ClockType, ROSClock
from .exceptions import (
    InvalidNamespaceException,
    InvalidNodeNameException,
    InvalidParameterTypeException,
    InvalidParameterValueException,
    InvalidServiceNameException,
    InvalidTopicNameException,
    NotInitializedException,
    ParameterAlreadyDeclaredException,
    ParameterImmutableException,
    ParameterNotDeclaredException,
    ParameterUninitializedException,
)
from .logging import get_logger
from .parameter import PARAMETER_SEPARATOR_STRING, Parameter
from .task import Future
from .utilities import get_default_context

USE_SIM_TIME_NAME = "use_sim_time"


def _type_name(msg_type) -> str:
    return getattr(msg_type, "__msgtype__", None) or getattr(msg_type, "__srvtype__", None) or getattr(
        msg_type, "__actiontype__", repr(msg_type))


def _coerce_message(msg, msg_type):
    if type(msg) is msg_type:
        return msg
    if getattr(msg, "__msgtype__", None) == getattr(msg_type, "__msgtype__", object()):
        return _convert(msg)
    raise TypeError(f"Expected {msg_type}, got {type(msg)}")


# ----------------------------------------------------------------------------------------------
# Entities


class Publisher:
    def __init__(self, node: "Node", msg_type, topic: str, qos_profile: _qos.QoSProfile, callback_group=None):
        self._node = node
        self.msg_type = msg_type
        self.topic = topic
        self.qos_profile = qos_profile
        self.callback_group = callback_group
        self._latched: deque | None = (
            deque(maxlen=qos_profile.depth or None)
            if qos_profile.durability == _qos.DurabilityPolicy.TRANSIENT_LOCAL else None)

    @property
    def topic_name(self) -> str:
        return self.topic

    @property
    def handle(self):
        return self

    def publish(self, msg) -> None:
        """Queue a copy of `msg` for every matching subscription; callbacks run when spun."""
        if isinstance(msg, (bytes, bytearray, memoryview)):
            from prisma_bringup.typestore import get_typestore

            msg = get_typestore().deserialize_cdr(bytes(msg), self.msg_type.__msgtype__)
        msg = _coerce_message(msg, self.msg_type)
        context = self._node.context
        if not context.ok():
            raise RuntimeError("publish on a shut down context")
        if self._latched is not None:
            self._latched.append(_convert(msg))
        for subscription in list(context.graph.subscriptions):
            if subscription.topic_name == self.topic and subscription._accepts(self):
                subscription._enqueue(msg)

    def get_subscription_count(self) -> int:
        return sum(1 for s in self._node.context.graph.subscriptions
                   if s.topic_name == self.topic and s._accepts(self))

    def assert_liveliness(self) -> None:
        pass

    def wait_for_all_acked(self, timeout=None) -> bool:
        return True

    def destroy(self) -> None:
        self._node.destroy_publisher(self)


class Subscription:
    def __init__(self, node: "Node", msg_type, topic: str, callback: Callable, qos_profile: _qos.QoSProfile,
                 callback_group=None, raw: bool = False):
        self._node = node
        self.msg_type = msg_type
        self.topic = topic
        self.callback = callback
        self.qos_profile = qos_profile
        self.callback_group = callback_group
        self.raw = raw
        keep_last = qos_profile.history != _qos.HistoryPolicy.KEEP_ALL and qos_profile.depth > 0
        self._inbox: deque = deque(maxlen=qos_profile.depth if keep_last else None)

    @property
    def topic_name(self) -> str:
        return self.topic

    @property
    def handle(self):
        return self

    def _accepts(self, publisher: Publisher) -> bool:
        return (_type_name(publisher.msg_type) == _type_name(self.msg_type)
                and _qos.compatible(publisher.qos_profile, self.qos_profile))

    def _enqueue(self, msg) -> None:
        # What the subscriber's rclpy would build from the wire: a fresh message, rclpy containers.
        self._inbox.append(_convert(msg))
        self._node.context.post(self._node, self._take_and_call, f"message on {self.topic}")

    def _take_and_call(self) -> bool:
        # More queued work items than messages means KEEP_LAST dropped the oldest ones.
        if not self._inbox or self not in self._node.context.graph.subscriptions:
            return False
        msg = self._inbox.popleft()
        if self.raw:
            from prisma_bringup.typestore import get_typestore

            msg = bytes(get_typestore().serialize_cdr(msg, msg.__msgtype__))
        self._node._run_callback(self.callback, msg)
        return True

    def destroy(self) -> None:
        self._node.destroy_subscription(self)


class Timer:
    def __init__(self, node: "Node", callback: Callable, period_ns: int, clock: Clock, callback_group=None,
                 autostart: bool = True):
        self._node = node
        self.callback = callback
        self._period_ns = int(period_ns)
        self._clock = clock
        self.callback_group = callback_group
        self._canceled = not autostart
        now = _test_clock.now_ns()
        self._last_call_ns = now
        self._next_call_ns = now + self._period_ns
        self._order = node.context.next_sequence()

    @property
    def timer_period_ns(self) -> int:
        return self._period_ns

    @timer_period_ns.setter
    def timer_period_ns(self, value: int) -> None:
        self._period_ns = int(value)
        self.reset()

    @property
    def clock(self) -> Clock:
        return self._clock

    @property
    def handle(self):
        return self

    def is_canceled(self) -> bool:
        return self._canceled

    def cancel(self) -> None:
        self._canceled = True

    def reset(self) -> None:
        self._canceled = False
        now = _test_clock.now_ns()
        self._next_call_ns = now + self._period_ns

    def is_ready(self) -> bool:
        return not self._canceled and _test_clock.now_ns() >= self._next_call_ns

    def time_until_next_call(self) -> int | None:
        if self._canceled:
            return None
        return self._next_call_ns - _test_clock.now_ns()

    def time_since_last_call(self) -> int:
        return _test_clock.now_ns() - self._last_call_ns

    def _fire(self) -> None:
        now = _test_clock.now_ns()
        self._last_call_ns = now
        self._next_call_ns += self._period_ns
        if self._period_ns > 0 and now >= self._next_call_ns:
            # Like rcl: periods missed while nobody spun are skipped, not replayed.
            missed = (now - self._next_call_ns) // self._period_ns + 1
            self._next_call_ns += missed * self._period_ns
        self._node._run_callback(self.callback)

    def destroy(self) -> None:
        self._node.destroy_timer(self)


class Service:
    def __init__(self, node: "Node", srv_type, srv_name: str, callback: Callable, qos_profile, callback_group=None):
        self._node = node
        self.srv_type = srv_type
        self.srv_name = srv_name
        self.callback = callback
        self.qos_profile = qos_profile
        self.callback_group = callback_group

    @property
    def service_name(self) -> str:
        return self.srv_name

    @property
    def handle(self):
        return self

    def _handle_request(self, request, respond: Callable[[Any], None]) -> bool:
        if self not in self._node.context.graph.services:
            return False

        def finish(response):
            if not isinstance(response, self.srv_type.Response):
                self._node.get_logger().error(
                    f"service {self.srv_name} callback returned {type(response)}, "
                    f"expected {self.srv_type.Response}")
                return
            respond(response)

        self._node._run_callback(self.callback, request, self.srv_type.Response(), on_done=finish)
        return True

    def destroy(self) -> None:
        self._node.destroy_service(self)


class Client:
    def __init__(self, node: "Node", srv_type, srv_name: str, qos_profile, callback_group=None):
        self._node = node
        self.srv_type = srv_type
        self.srv_name = srv_name
        self.qos_profile = qos_profile
        self.callback_group = callback_group
        self._pending: dict[int, Future] = {}

    @property
    def service_name(self) -> str:
        return self.srv_name

    @property
    def handle(self):
        return self

    def _server(self) -> Service | None:
        for service in self._node.context.graph.services:
            if service.srv_name == self.srv_name and _type_name(service.srv_type) == _type_name(self.srv_type):
                return service
        return None

    def call_async(self, request) -> Future:
        """Send the request; the returned Future completes when the client's node is spun after
        the server's node handled it (as in rclpy). Without a server the Future stays pending."""
        request = _coerce_message(request, self.srv_type.Request)
        future = Future()
        sequence = self._node.context.next_sequence()
        self._pending[sequence] = future
        server = self._server()
        if server is not None:
            request = _convert(request)

            def respond(response, sequence=sequence):
                response = _convert(response)
                self._node.context.post(
                    self._node, lambda: self._deliver(sequence, response), f"response on {self.srv_name}")

            self._node.context.post(server._node, lambda: server._handle_request(request, respond),
                                    f"request on {self.srv_name}")
        return future

    def _deliver(self, sequence: int, response) -> bool:
        future = self._pending.pop(sequence, None)
        if future is None or future.done():
            return False
        future.set_result(response)
        return True

    def call(self, request, timeout_sec=None):
        raise RuntimeError(
            "Client.call() blocks until another thread spins the node; use call_async() and "
            "spin (ros.spin_until(future)) in stand-in tests")

    def remove_pending_request(self, future: Future) -> None:
        for key, value in list(self._pending.items()):
            if value is future:
                del self._pending[key]

    def service_is_ready(self) -> bool:
        return self._server() is not None

    def wait_for_service(self, timeout_sec: float | None = None) -> bool:
        # Nothing else can create a server while this call waits, so there is nothing to wait for.
        return self.service_is_ready()

    def destroy(self) -> None:
        self._node.destroy_client(self)


# ----------------------------------------------------------------------------------------------
# Node


class Node:
    PARAM_REL_TOL = 1e-6

    def __init__(
        self,
        node_name: str,
        *,
        context=None,
        cli_args=None,
        namespace: str | None = None,
        use_global_arguments: bool = True,
        enable_rosout: bool = True,
        start_parameter_services: bool = True,
        parameter_overrides: list[Parameter] | None = None,
        allow_undeclared_parameters: bool = False,
        automatically_declare_parameters_from_overrides: bool = False,
        enable_logger_service: bool = False,
    ) -> None:
        self._context = get_default_context() if context is None else context
        if not self._context.ok():
            raise NotInitializedException("cannot create node")
        error = _names.validate_node_name(node_name)
        if error:
            raise InvalidNodeNameException(node_name, error, 0)
        namespace = _names.normalize_namespace(namespace)
        error = _names.validate_namespace(namespace)
        if error:
            raise InvalidNamespaceException(namespace, error, 0)
        self._name = node_name
        self._namespace = namespace
        self._parameters: dict[str, Parameter] = {}
        self._descriptors: dict[str, ParameterDescriptor] = {}
        self._pre_set_parameters_callbacks: list = []
        self._on_set_parameters_callbacks: list = []
        self._post_set_parameters_callbacks: list = []
        self._allow_undeclared_parameters = allow_undeclared_parameters
        self._publishers: list[Publisher] = []
        self._subscriptions: list[Subscription] = []
        self._timers: list[Timer] = []
        self._services: list[Service] = []
        self._clients: list[Client] = []
        self._waitables: list = []
        self._guards: list = []
        self._executor = None
        self._destroyed = False
        self._default_callback_group = MutuallyExclusiveCallbackGroup()
        self._clock = ROSClock()
        logger_name = (namespace.strip("/").replace("/", ".") + "." if namespace != "/" else "") + node_name
        self._logger = get_logger(logger_name)

        entries = []
        if use_global_arguments:
            entries.extend(self._context.parameter_overrides)
        if cli_args:
            entries.extend(_arguments.parse_ros_args(cli_args)[0])
        self._parameter_overrides: dict[str, Parameter] = {
            name: Parameter(name, value=value)
            for name, value in _arguments.overrides_for(entries, self.get_fully_qualified_name()).items()
        }
        for parameter in parameter_overrides or []:
            if not isinstance(parameter, Parameter):
                raise TypeError("parameter_overrides must be a list of rclpy.parameter.Parameter")
            self._parameter_overrides[parameter.name] = parameter
        if automatically_declare_parameters_from_overrides:
            self.declare_parameters("", [(p.name, p.value) for p in self._parameter_overrides.values()])

        if not self.has_parameter(USE_SIM_TIME_NAME):
            self.declare_parameter(USE_SIM_TIME_NAME, False)
        use_sim_time = self.get_parameter(USE_SIM_TIME_NAME).value
        self._clock._set_ros_time_is_active(bool(use_sim_time))

        self._context.graph.nodes.append(self)
        for hook in list(self._context.graph.node_created_hooks):
            hook(self)

    # -- identity ----------------------------------------------------------------------------

    @property
    def context(self):
        return self._context

    @property
    def handle(self):
        return self

    @property
    def executor(self):
        return self._executor

    @executor.setter
    def executor(self, new_executor) -> None:
        if new_executor is self._executor:
            return
        if self._executor is not None:
            self._executor.remove_node(self)
        if new_executor is not None:
            new_executor.add_node(self)

    @property
    def default_callback_group(self) -> CallbackGroup:
        return self._default_callback_group

    def get_name(self) -> str:
        return self._name

    def get_namespace(self) -> str:
        return self._namespace

    def get_fully_qualified_name(self) -> str:
        return self._namespace.rstrip("/") + "/" + self._name

    def get_clock(self) -> Clock:
        return self._clock

    def get_logger(self):
        return self._logger

    def resolve_topic_name(self, topic: str, *, only_expand: bool = False) -> str:
        return self._resolve(topic, InvalidTopicNameException)

    def resolve_service_name(self, service: str, *, only_expand: bool = False) -> str:
        return self._resolve(service, InvalidServiceNameException)

    def _resolve(self, name: str, error_type) -> str:
        if not isinstance(name, str) or not name:
            raise error_type(str(name), "name must not be empty", 0)
        expanded = _names.expand_topic_name(name, self._name, self._namespace)
        error = _names.validate_full_topic_name(expanded)
        if error:
            raise error_type(name, error, 0)
        return expanded

    # -- entities ----------------------------------------------------------------------------

    @property
    def publishers(self) -> Iterator[Publisher]:
        yield from self._publishers

    @property
    def subscriptions(self) -> Iterator[Subscription]:
        yield from self._subscriptions

    @property
    def timers(self) -> Iterator[Timer]:
        yield from self._timers

    @property
    def services(self) -> Iterator[Service]:
        yield from self._services

    @property
    def clients(self) -> Iterator[Client]:
        yield from self._clients

    @property
    def guards(self) -> Iterator:
        yield from self._guards

    @property
    def waitables(self) -> Iterator:
        yield from self._waitables

    def _check_alive(self) -> None:
        if self._destroyed:
            from ._rclpy_pybind11 import RCLError

            raise RCLError(f"node '{self._name}' has been destroyed")

    def create_publisher(self, msg_type, topic: str, qos_profile, *, callback_group=None,
                         event_callbacks=None, qos_overriding_options=None, publisher_class=None) -> Publisher:
        self._check_alive()
        profile = _qos.as_profile(qos_profile)
        publisher = Publisher(self, msg_type, self.resolve_topic_name(topic), profile,
                              callback_group or self._default_callback_group)
        self._publishers.append(publisher)
        self._context.graph.publishers.append(publisher)
        return publisher

    def create_subscription(self, msg_type, topic: str, callback: Callable, qos_profile, *,
                            callback_group=None, event_callbacks=None, qos_overriding_options=None,
                            raw: bool = False) -> Subscription:
        self._check_alive()
        profile = _qos.as_profile(qos_profile)
        subscription = Subscription(self, msg_type, self.resolve_topic_name(topic), callback, profile,
                                    callback_group or self._default_callback_group, raw)
        self._subscriptions.append(subscription)
        self._context.graph.subscriptions.append(subscription)
        if profile.durability == _qos.DurabilityPolicy.TRANSIENT_LOCAL:
            for publisher in self._context.graph.publishers:
                if (publisher.topic == subscription.topic and publisher._latched is not None
                        and subscription._accepts(publisher)):
                    for msg in publisher._latched:
                        subscription._enqueue(msg)
        return subscription

    def create_timer(self, timer_period_sec: float, callback: Callable, callback_group=None,
                     clock: Clock | None = None, autostart: bool = True) -> Timer:
        self._check_alive()
        period_ns = int(float(timer_period_sec) * 1e9)
        if period_ns < 0:
            raise ValueError("timer period must not be negative")
        timer = Timer(self, callback, period_ns, clock or self._clock,
                      callback_group or self._default_callback_group, autostart)
        self._timers.append(timer)
        return timer

    def create_service(self, srv_type, srv_name: str, callback: Callable, *,
                       qos_profile=_qos.qos_profile_services_default, callback_group=None) -> Service:
        self._check_alive()
        service = Service(self, srv_type, self.resolve_service_name(srv_name), callback, qos_profile,
                          callback_group or self._default_callback_group)
        self._services.append(service)
        self._context.graph.services.append(service)
        return service

    def create_client(self, srv_type, srv_name: str, *, qos_profile=_qos.qos_profile_services_default,
                      callback_group=None) -> Client:
        self._check_alive()
        client = Client(self, srv_type, self.resolve_service_name(srv_name), qos_profile,
                        callback_group or self._default_callback_group)
        self._clients.append(client)
        self._context.graph.clients.append(client)
        return client

    def create_rate(self, frequency: float, clock: Clock | None = None):
        raise NotImplementedError("Rate.sleep() blocks; use a timer (the stand-in test clock drives timers)")

    def create_guard_condition(self, callback: Callable, callback_group=None):
        raise NotImplementedError("guard conditions are not part of the stand-in")

    def _remove(self, entity, own: list, graph_list: list | None) -> bool:
        if entity not in own:
            return False
        own.remove(entity)
        if graph_list is not None and entity in graph_list:
            graph_list.remove(entity)
        return True

    def destroy_publisher(self, publisher: Publisher) -> bool:
        return self._remove(publisher, self._publishers, self._context.graph.publishers)

    def destroy_subscription(self, subscription: Subscription) -> bool:
        return self._remove(subscription, self._subscriptions, self._context.graph.subscriptions)

    def destroy_timer(self, timer: Timer) -> bool:
        timer._canceled = True
        return self._remove(timer, self._timers, None)

    def destroy_service(self, service: Service) -> bool:
        return self._remove(service, self._services, self._context.graph.services)

    def destroy_client(self, client: Client) -> bool:
        return self._remove(client, self._clients, self._context.graph.clients)

    def add_waitable(self, waitable) -> None:
        self._waitables.append(waitable)

    def remove_waitable(self, waitable) -> None:
        if waitable in self._waitables:
            self._waitables.remove(waitable)

    def destroy_node(self) -> None:
        if self._destroyed:
            return
        for waitable in list(self._waitables):
            destroy = getattr(waitable, "destroy", None)
            if destroy is not None:
                destroy()
        for publisher in list(self._publishers):
            self.destroy_publisher(publisher)
        for subscription in list(self._subscriptions):
            self.destroy_subscription(subscription)
        for timer in list(self._timers):
            self.destroy_timer(timer)
        for service in list(self._services):
            self.destroy_service(service)
        for client in list(self._clients):
            self.destroy_client(client)
        if self._executor is not None:
            self._executor.remove_node(self)
        if self in self._context.graph.nodes:
            self._context.graph.nodes.remove(self)
        self._destroyed = True

    # -- callbacks (run by executors) ---------------------------------------------------------

    def _run_callback(self, callback: Callable, *args, on_done: Callable | None = None) -> None:
        """Call a user callback; a coroutine it returns becomes a task of this node's executor."""
        result = callback(*args)
        if inspect.iscoroutine(result):
            executor = self._executor
            if executor is None:
                raise RuntimeError(f"node '{self._name}' has no executor to run a coroutine callback")
            task = executor.create_task(result)
            if on_done is not None:
                task.add_done_callback(lambda t: on_done(t.result()) if t.exception() is None else None)
            executor._run_task(task)
        elif on_done is not None:
            on_done(result)

    # -- graph queries -----------------------------------------------------------------------

    def get_node_names(self) -> list[str]:
        return [n.get_name() for n in self._context.graph.nodes]

    def get_node_names_and_namespaces(self) -> list[tuple[str, str]]:
        return [(n.get_name(), n.get_namespace()) for n in self._context.graph.nodes]

    def _names_and_types(self, entities, name_attr: str, type_attr: str) -> list[tuple[str, list[str]]]:
        found: dict[str, list[str]] = {}
        for entity in entities:
            types = found.setdefault(getattr(entity, name_attr), [])
            type_name = _type_name(getattr(entity, type_attr))
            if type_name not in types:
                types.append(type_name)
        return sorted(found.items())

    def _node_by_name(self, node_name: str, node_namespace: str) -> "Node":
        namespace = _names.normalize_namespace(node_namespace)
        for node in self._context.graph.nodes:
            if node.get_name() == node_name and node.get_namespace() == namespace:
                return node
        from ._rclpy_pybind11 import RCLError

        raise RCLError(f"cannot get names and types: node '{node_name}' in '{namespace}' not found")

    def get_topic_names_and_types(self, no_demangle: bool = False) -> list[tuple[str, list[str]]]:
        graph = self._context.graph
        return self._names_and_types(list(graph.publishers) + list(graph.subscriptions), "topic", "msg_type")

    def get_service_names_and_types(self) -> list[tuple[str, list[str]]]:
        graph = self._context.graph
        return self._names_and_types(list(graph.services) + list(graph.clients), "srv_name", "srv_type")

    def get_publisher_names_and_types_by_node(self, node_name: str, node_namespace: str,
                                              no_demangle: bool = False):
        node = self._node_by_name(node_name, node_namespace)
        return self._names_and_types(node._publishers, "topic", "msg_type")

    def get_subscriber_names_and_types_by_node(self, node_name: str, node_namespace: str,
                                               no_demangle: bool = False):
        node = self._node_by_name(node_name, node_namespace)
        return self._names_and_types(node._subscriptions, "topic", "msg_type")

    def get_service_names_and_types_by_node(self, node_name: str, node_namespace: str):
        node = self._node_by_name(node_name, node_namespace)
        return self._names_and_types(node._services, "srv_name", "srv_type")

    def get_client_names_and_types_by_node(self, node_name: str, node_namespace: str):
        node = self._node_by_name(node_name, node_namespace)
        return self._names_and_types(node._clients, "srv_name", "srv_type")

    def count_publishers(self, topic_name: str) -> int:
        topic = self.resolve_topic_name(topic_name)
        return sum(1 for p in self._context.graph.publishers if p.topic == topic)

    def count_subscribers(self, topic_name: str) -> int:
        topic = self.resolve_topic_name(topic_name)
        return sum(1 for s in self._context.graph.subscriptions if s.topic == topic)

    # -- parameters --------------------------------------------------------------------------

    def declare_parameter(self, name: str, value: Any = None, descriptor: ParameterDescriptor | None = None,
                          ignore_override: bool = False) -> Parameter:
        if value is None and descriptor is None:
            args = (name,)
        else:
            descriptor = ParameterDescriptor() if descriptor is None else descriptor
            args = (name, value, descriptor)
        return self.declare_parameters("", [args], ignore_override)[0]

    def declare_parameters(self, namespace: str, parameters: list[tuple], ignore_override: bool = False) -> list[Parameter]:
        parameter_list: list[Parameter] = []
        descriptors: dict[str, ParameterDescriptor] = {}
        for index, parameter_tuple in enumerate(parameters):
            if len(parameter_tuple) < 1 or len(parameter_tuple) > 3:
                raise TypeError(
                    f"Invalid parameter tuple length at index {index} in parameters list: "
                    f"{parameter_tuple}; expecting length between 1 and 3")
            name = parameter_tuple[0]
            if not isinstance(name, str):
                raise TypeError(f"First element {name} at index {index} in parameters list is not a str.")
            if namespace:
                name = f"{namespace}.{name}"
            second = parameter_tuple[1] if len(parameter_tuple) > 1 else None
            descriptor = parameter_tuple[2] if len(parameter_tuple) > 2 else ParameterDescriptor()
            if not isinstance(descriptor, ParameterDescriptor):
                raise TypeError(f"Third element {descriptor} at index {index} in parameters list "
                                "is not a ParameterDescriptor.")
            value = None
            if len(parameter_tuple) == 1:
                warnings.warn(f"when declaring parameter named '{name}', declaring a parameter only "
                              "providing its name is deprecated.", stacklevel=3)
                descriptor.dynamic_typing = True
            if isinstance(second, Parameter.Type):
                if second == Parameter.Type.NOT_SET:
                    raise ValueError(f"Cannot declare parameter {{{name}}} as statically typed of type NOT_SET")
                if descriptor.dynamic_typing:
                    raise ValueError(f"When declaring parameter {{{name}}} passing a descriptor with "
                                     "`dynamic_typing=True` is not allowed when the parameter type is provided")
                descriptor.type = second.value
            else:
                value = second
                if not descriptor.dynamic_typing:
                    descriptor.type = Parameter.Type.from_parameter_value(value).value
                    if descriptor.type == Parameter.Type.NOT_SET.value:
                        raise ValueError("Cannot declare a statically typed parameter with default value "
                                         "of type PARAMETER_NOT_SET")
            if not ignore_override and name in self._parameter_overrides:
                value = self._parameter_overrides[name].value
            parameter_list.append(Parameter(name, value=value))
            descriptors[name] = descriptor

        already = [p.name for p in parameter_list if p.name in self._parameters]
        if already:
            raise ParameterAlreadyDeclaredException(already)
        for parameter in parameter_list:
            result = self._set_parameters_atomically_common([parameter], descriptors, allow_not_set_type=True)
            if not result.successful:
                if result.reason.startswith("Wrong parameter type"):
                    raise InvalidParameterTypeException(
                        parameter, Parameter.Type(descriptors[parameter.name].type).name)
                raise InvalidParameterValueException(parameter.name, parameter.value, result.reason)
        return [self._parameters[p.name] for p in parameter_list]

    def undeclare_parameter(self, name: str) -> None:
        if not self.has_parameter(name):
            raise ParameterNotDeclaredException(name)
        if self._descriptors[name].read_only:
            raise ParameterImmutableException(name)
        del self._parameters[name]
        del self._descriptors[name]

    def has_parameter(self, name: str) -> bool:
        return name in self._parameters

    def get_parameter(self, name: str) -> Parameter:
        if self.has_parameter(name):
            parameter = self._parameters[name]
            if parameter.type_ != Parameter.Type.NOT_SET or self._descriptors[name].dynamic_typing:
                return parameter
            raise ParameterUninitializedException(name)
        if self._allow_undeclared_parameters:
            return Parameter(name, Parameter.Type.NOT_SET, None)
        raise ParameterNotDeclaredException(name)

    def get_parameters(self, names: list[str]) -> list[Parameter]:
        if not all(isinstance(name, str) for name in names):
            raise TypeError("All names must be instances of type str")
        return [self.get_parameter(name) for name in names]

    def get_parameter_or(self, name: str, alternative_value: Parameter | None = None) -> Parameter:
        if alternative_value is None:
            alternative_value = Parameter(name, Parameter.Type.NOT_SET)
        if not self.has_parameter(name) or self._parameters[name].type_ == Parameter.Type.NOT_SET:
            return alternative_value
        return self._parameters[name]

    def get_parameter_type(self, name: str) -> Parameter.Type:
        if self.has_parameter(name):
            return self._parameters[name].type_
        if self._allow_undeclared_parameters:
            return Parameter.Type.NOT_SET
        raise ParameterNotDeclaredException(name)

    def get_parameters_by_prefix(self, prefix: str) -> dict[str, Parameter]:
        if prefix:
            prefix = prefix + PARAMETER_SEPARATOR_STRING
        return {name[len(prefix):]: value for name, value in self._parameters.items() if name.startswith(prefix)}

    def list_parameters(self, prefixes: list[str], depth: int):
        """Declared names under `prefixes` (all when empty), down to `depth` dots (0 = unlimited)."""
        from rcl_interfaces.msg import ListParametersResult

        if depth < 0:
            raise ValueError("The depth must be greater than or equal to zero")
        result = ListParametersResult()
        names, found_prefixes = [], []
        for name in self._parameters:
            relative = name
            if prefixes:
                match = next((p for p in prefixes if name == p or name.startswith(p + PARAMETER_SEPARATOR_STRING)), None)
                if match is None:
                    continue
                relative = name[len(match) + 1:]
            if depth and relative.count(PARAMETER_SEPARATOR_STRING) >= depth:
                continue
            names.append(name)
            if PARAMETER_SEPARATOR_STRING in name:
                prefix = name.rsplit(PARAMETER_SEPARATOR_STRING, 1)[0]
                if prefix not in found_prefixes:
                    found_prefixes.append(prefix)
        result.names = names
        result.prefixes = found_prefixes
        return result

    def describe_parameter(self, name: str) -> ParameterDescriptor:
        try:
            return self._descriptors[name]
        except KeyError:
            if self._allow_undeclared_parameters:
                return ParameterDescriptor()
            raise ParameterNotDeclaredException(name) from None

    def describe_parameters(self, names: list[str]) -> list[ParameterDescriptor]:
        return [self.describe_parameter(name) for name in names]

    def set_parameters(self, parameter_list: list[Parameter]) -> list[SetParametersResult]:
        return [self._set_parameters_atomically([parameter]) for parameter in parameter_list]

    def set_parameters_atomically(self, parameter_list: list[Parameter]) -> SetParametersResult:
        return self._set_parameters_atomically(parameter_list)

    def _set_parameters_atomically(self, parameter_list: list[Parameter]) -> SetParametersResult:
        if self._pre_set_parameters_callbacks:
            modified: list[Parameter] = []
            for callback in self._pre_set_parameters_callbacks:
                modified.extend(callback(parameter_list))
            parameter_list = modified
            if not parameter_list:
                return SetParametersResult(
                    successful=False,
                    reason="parameter list cannot be empty, this might be due to pre_set_parameters_callback "
                           "modifying the original parameters list.")
        if not all(isinstance(p, Parameter) for p in parameter_list):
            raise TypeError("parameter must be instance of type '{}'".format(repr(Parameter)))
        undeclared = [p.name for p in parameter_list if p.name not in self._parameters]
        if undeclared and not self._allow_undeclared_parameters:
            raise ParameterNotDeclaredException(undeclared)
        return self._set_parameters_atomically_common(parameter_list)

    def _set_parameters_atomically_common(self, parameter_list, descriptors=None,
                                          allow_not_set_type: bool = False) -> SetParametersResult:
        if descriptors is not None:
            result = self._apply_descriptors(parameter_list, descriptors, False)
        else:
            result = self._apply_descriptors(parameter_list, self._descriptors, True)
        if not result.successful:
            return result
        for callback in self._on_set_parameters_callbacks:
            result = callback(parameter_list)
            if not isinstance(result, SetParametersResult):
                raise TypeError("on-set-parameters callbacks must return rcl_interfaces.msg.SetParametersResult")
            if not result.successful:
                return result
        for parameter in parameter_list:
            if not allow_not_set_type and parameter.type_ == Parameter.Type.NOT_SET:
                self._parameters.pop(parameter.name, None)
                self._descriptors.pop(parameter.name, None)
                continue
            if descriptors is not None:
                self._descriptors[parameter.name] = descriptors[parameter.name]
            elif parameter.name not in self._descriptors:
                self._descriptors[parameter.name] = ParameterDescriptor(dynamic_typing=True)
            self._parameters[parameter.name] = parameter
            if parameter.name == USE_SIM_TIME_NAME and parameter.type_ == Parameter.Type.BOOL:
                self._clock._set_ros_time_is_active(parameter.value)
        for callback in self._post_set_parameters_callbacks:
            callback(parameter_list)
        return SetParametersResult(successful=True)

    def _apply_descriptors(self, parameter_list, descriptors, check_read_only: bool) -> SetParametersResult:
        for parameter in parameter_list:
            if parameter.name in descriptors:
                result = self._apply_descriptor(parameter, descriptors[parameter.name], check_read_only)
                if not result.successful:
                    return result
        return SetParametersResult(successful=True)

    def _apply_descriptor(self, parameter: Parameter, descriptor: ParameterDescriptor,
                          check_read_only: bool) -> SetParametersResult:
        descriptor.name = parameter.name
        if check_read_only and descriptor.read_only:
            return SetParametersResult(successful=False,
                                       reason=f"Trying to set a read-only parameter: {parameter.name}.")
        if descriptor.dynamic_typing:
            descriptor.type = parameter.type_.value
        elif self.has_parameter(parameter.name) and parameter.type_ == Parameter.Type.NOT_SET:
            return SetParametersResult(successful=False, reason="Static parameter cannot be undeclared")
        elif parameter.type_ != Parameter.Type.NOT_SET and parameter.type_.value != descriptor.type:
            return SetParametersResult(
                successful=False,
                reason=f"Wrong parameter type, expected '{Parameter.Type(descriptor.type)}' got '{parameter.type_}'")
        if parameter.type_ == Parameter.Type.INTEGER and len(descriptor.integer_range):
            bounds = descriptor.integer_range[0]
            low, high = sorted((bounds.from_value, bounds.to_value))
            value = parameter.value
            if value not in (low, high):
                if not low < value < high:
                    return SetParametersResult(
                        successful=False,
                        reason=f"Parameter {parameter.name} out of range. Min: {low}, Max: {high}, value: {value}")
                if bounds.step and (value - low) % bounds.step:
                    return SetParametersResult(
                        successful=False,
                        reason=f"The parameter value for {parameter.name} is not a valid step. "
                               f"Min: {low}, max: {high}, value: {value}, step: {bounds.step}")
        if parameter.type_ == Parameter.Type.DOUBLE and len(descriptor.floating_point_range):
            bounds = descriptor.floating_point_range[0]
            low, high = sorted((bounds.from_value, bounds.to_value))
            value = parameter.value
            at_edge = (math.isclose(value, low, rel_tol=self.PARAM_REL_TOL)
                       or math.isclose(value, high, rel_tol=self.PARAM_REL_TOL))
            if not at_edge:
                if not low < value < high:
                    return SetParametersResult(
                        successful=False,
                        reason=f"Parameter {parameter.name} out of range Min: {low}, Max: {high}, value: {value}")
                if bounds.step:
                    steps = round((value - low) / bounds.step)
                    if not math.isclose(low + steps * bounds.step, value, rel_tol=self.PARAM_REL_TOL):
                        return SetParametersResult(
                            successful=False,
                            reason=f"The parameter value for {parameter.name} is not close enough to a valid step. "
                                   f"Min: {low}, max: {high}, value: {value}, step: {bounds.step}")
        return SetParametersResult(successful=True)

    def add_pre_set_parameters_callback(self, callback) -> None:
        self._pre_set_parameters_callbacks.insert(0, callback)

    def add_on_set_parameters_callback(self, callback) -> None:
        self._on_set_parameters_callbacks.insert(0, callback)

    def add_post_set_parameters_callback(self, callback) -> None:
        self._post_set_parameters_callbacks.insert(0, callback)

    def remove_pre_set_parameters_callback(self, callback) -> None:
        self._pre_set_parameters_callbacks.remove(callback)

    def remove_on_set_parameters_callback(self, callback) -> None:
        self._on_set_parameters_callbacks.remove(callback)

    def remove_post_set_parameters_callback(self, callback) -> None:
        self._post_set_parameters_callbacks.remove(callback)

    def __repr__(self) -> str:
        return f"<Node {self.get_fully_qualified_name()}>"
