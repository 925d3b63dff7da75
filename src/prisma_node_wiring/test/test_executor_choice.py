"""executor_choice: which executor PRISMA_EXECUTOR and the running rclpy's version give, and why, without
ROS (the self-test faked: it runs only where the fast executor could be chosen)."""
from __future__ import annotations

import importlib.metadata

import pytest

from prisma_node_wiring import executor_choice
from prisma_node_wiring.executor_choice import (
    EXECUTOR_ENV,
    ExecutorChoice,
    choose_executor,
    package_xml_version,
    rclpy_version,
    requested_executor,
)


class SelfTest:
    """A fake fast-executor self-test: its answer, and how often it ran."""

    def __init__(self, failure: str | None = None) -> None:
        self.failure = failure
        self.runs = 0

    def __call__(self) -> str | None:
        self.runs += 1
        return self.failure


def test_auto_on_the_proven_rclpy_keeps_the_fast_executor_once_its_self_test_passed():
    self_test = SelfTest()
    choice = choose_executor("auto", "7.1.3", self_test, events_available=False)
    assert choice == ExecutorChoice("fast", "PRISMA_EXECUTOR=auto: rclpy 7.1.3 is proven and the self-test passed")
    assert self_test.runs == 1
    assert choice.log_line() == ("executor: fast, SingleWaitExecutor (prisma_node_wiring.executor): "
                                 "PRISMA_EXECUTOR=auto: rclpy 7.1.3 is proven and the self-test passed")


@pytest.mark.parametrize("version", ["7.1.9", "7.1.11", "3.3.16", "7.1.3.post1", None])
def test_auto_on_any_other_rclpy_is_stock_without_trying_the_fast_one(version):
    self_test = SelfTest()
    choice = choose_executor("auto", version, self_test, events_available=True)
    assert choice.kind == "stock"
    running = f"rclpy {version}" if version else "an rclpy of unknown version"
    assert choice.reason == f"PRISMA_EXECUTOR=auto: {running} is not one the fast executor is proven on (7.1.3)"
    assert self_test.runs == 0


def test_a_failed_self_test_on_the_proven_rclpy_is_stock_naming_the_failure():
    choice = choose_executor("auto", "7.1.3", SelfTest("rclpy's SingleThreadedExecutor has no _make_handler"),
                             events_available=False)
    assert choice == ExecutorChoice("stock", "PRISMA_EXECUTOR=auto: the fast executor's self-test failed on "
                                             "rclpy 7.1.3: rclpy's SingleThreadedExecutor has no _make_handler")


def test_fast_asked_where_it_cannot_be_honoured_says_refused_and_falls_back():
    unproven = choose_executor("fast", "7.1.9", SelfTest(), events_available=True)
    assert unproven == ExecutorChoice("stock", "PRISMA_EXECUTOR=fast, refused: rclpy 7.1.9 is not one the fast "
                                               "executor is proven on (7.1.3)")
    failed = choose_executor("fast", "7.1.3", SelfTest("no message"), events_available=False)
    assert failed.kind == "stock" and failed.reason.startswith("PRISMA_EXECUTOR=fast, refused: the fast executor's")
    assert choose_executor("fast", "7.1.3", SelfTest(), events_available=False).kind == "fast"


def test_stock_asked_is_stock_on_every_rclpy_without_a_self_test():
    self_test = SelfTest()
    for version in ("7.1.3", "7.1.11", None):
        choice = choose_executor("stock", version, self_test, events_available=True)
        assert choice == ExecutorChoice("stock", "PRISMA_EXECUTOR=stock")
    assert self_test.runs == 0
    assert choice.log_line() == "executor: stock, rclpy's SingleThreadedExecutor: PRISMA_EXECUTOR=stock"


def test_events_asked_is_rclpys_events_executor_where_it_exists_and_stock_where_not():
    events = choose_executor("events", "7.1.11", SelfTest(), events_available=True)
    assert events.log_line() == ("executor: events, rclpy.experimental.EventsExecutor, untested in this suite: "
                                 "PRISMA_EXECUTOR=events")
    missing = choose_executor("events", "7.1.3", SelfTest(), events_available=False)
    assert missing == ExecutorChoice("stock", "PRISMA_EXECUTOR=events, but rclpy 7.1.3 has no "
                                              "rclpy.experimental.EventsExecutor (rclpy 7.1.4 on): falling back")


@pytest.mark.parametrize(("value", "requested"), [(None, "auto"), ("", "auto"), ("stock", "stock"),
                                                  (" Fast ", "fast"), ("events", "events"), ("auto", "auto")])
def test_the_request_is_read_from_prisma_executor(value, requested):
    env = {} if value is None else {EXECUTOR_ENV: value}
    assert requested_executor(env) == requested


@pytest.mark.parametrize("value", ["single_wait", "rclpy", "1", "stock,fast"])
def test_a_request_naming_no_executor_is_one_line_naming_the_value_and_the_choices(value):
    with pytest.raises(ValueError) as raised:
        requested_executor({EXECUTOR_ENV: value})
    assert str(raised.value) == (f"PRISMA_EXECUTOR={value!r} is not an executor: set it to one of auto, fast, "
                                 "stock, events (or leave it unset for auto)")


def test_rclpys_version_comes_from_its_package_xml_where_python_has_no_metadata(tmp_path, monkeypatch):
    def no_metadata(name: str) -> str:
        raise importlib.metadata.PackageNotFoundError(name)

    monkeypatch.setattr(executor_choice.importlib.metadata, "version", no_metadata)
    share = tmp_path / "jazzy" / "share" / "rclpy"
    share.mkdir(parents=True)
    (share / "package.xml").write_text('<?xml version="1.0"?>\n<package format="3"><name>rclpy</name>'
                                       "<version> 7.1.9 </version></package>\n")
    empty = tmp_path / "overlay"
    empty.mkdir()
    assert rclpy_version({"AMENT_PREFIX_PATH": f"{empty}:{tmp_path / 'jazzy'}"}) == "7.1.9"
    assert rclpy_version({"AMENT_PREFIX_PATH": str(empty)}) is None
    assert rclpy_version({}) is None


def test_a_package_xml_without_a_version_or_broken_gives_none(tmp_path):
    assert package_xml_version(tmp_path / "absent.xml") is None
    (tmp_path / "none.xml").write_text("<package><name>rclpy</name></package>")
    assert package_xml_version(tmp_path / "none.xml") is None
    (tmp_path / "broken.xml").write_text("<package><version>7.1.3</package>")
    assert package_xml_version(tmp_path / "broken.xml") is None
