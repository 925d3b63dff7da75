"""Bag layer: write prisma and standard messages, read them back with rosbags and mcap_ros2."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rosbags.highlevel import AnyReader

from prisma_common.bag import BagWriter, read_bag, stamp_ns
from prisma_common.typestore import get_typestore, types


def header(ns: int, frame: str = "thumb_pad"):
    Time = types("builtin_interfaces/msg/Time")
    return types("std_msgs/msg/Header")(stamp=Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id=frame)


def taxels(ns: int, base: int):
    counts = np.arange(base, base + 9, dtype=np.uint16)
    return types("prisma_msgs/msg/TaxelArray")(
        header=header(ns), finger="thumb", counts=counts,
        voltages=(counts * 3.3 / 4096).astype(np.float32))


def wrench(ns: int, fz: float):
    Vector3 = types("geometry_msgs/msg/Vector3")
    return types("geometry_msgs/msg/WrenchStamped")(
        header=header(ns), wrench=types("geometry_msgs/msg/Wrench")(
            force=Vector3(x=0.1, y=-0.2, z=fz), torque=Vector3(x=0.0, y=0.001, z=0.0)))


def contact(ns: int):
    return types("prisma_msgs/msg/ContactState")(
        header=header(ns), finger="thumb", voltages=np.full(9, 1.5, np.float32),
        mean_voltage=1.5, k=0.7, threshold=1.05, safe=np.array([True] * 8 + [False]),
        lost_edges=["left"], feasible=False)


def sample_stream():
    """Interleaved 100 Hz taxels + wrenches and a few contact states, 50 ms apart stamps."""
    stream = []
    for i in range(20):
        ns = 1_700_000_000_000_000_000 + i * 10_000_000
        stream.append(("/prisma/thumb/taxels", taxels(ns, 100 + i)))
        stream.append(("/prisma/thumb/wrench", wrench(ns, 0.05 * i)))
        if i % 5 == 0:
            stream.append(("/prisma/thumb/contact", contact(ns)))
    return stream


def write(path: Path, storage: str):
    stream = sample_stream()
    with BagWriter(path, storage=storage) as bag:
        bag.write_all(stream)
    return stream


def assert_messages_equal(expected, actual):
    store = get_typestore()
    assert expected.__msgtype__ == actual.__msgtype__
    raw_expected = bytes(store.serialize_cdr(expected, expected.__msgtype__))
    raw_actual = bytes(store.serialize_cdr(actual, actual.__msgtype__))
    assert raw_expected == raw_actual


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_anyreader_reads_back_message_for_message(tmp_path, storage):
    stream = write(tmp_path / "bag", storage)
    with AnyReader([tmp_path / "bag"], default_typestore=get_typestore()) as reader:
        got = [(c.topic, reader.deserialize(raw, c.msgtype), t)
               for c, t, raw in reader.messages()]
    assert len(got) == len(stream) == 44
    by_topic_expected: dict[str, list] = {}
    for topic, msg in stream:
        by_topic_expected.setdefault(topic, []).append(msg)
    for topic, expected in by_topic_expected.items():
        actual = [(m, t) for tp, m, t in got if tp == topic]
        assert len(actual) == len(expected)
        for e, (a, t) in zip(expected, actual):
            assert_messages_equal(e, a)
            assert t == stamp_ns(e)  # receive time = header stamp


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_read_bag_filters_topics_in_time_order(tmp_path, storage):
    write(tmp_path / "bag", storage)
    got = list(read_bag(tmp_path / "bag", topics=["/prisma/thumb/taxels"]))
    assert [m.message.counts[0] for m in got] == list(range(100, 120))
    assert all(b.timestamp_ns - a.timestamp_ns == 10_000_000 for a, b in zip(got, got[1:]))
    assert got[0].msgtype == "prisma_msgs/msg/TaxelArray"


def test_mcap_ros2_reader_decodes_every_message(tmp_path):
    from mcap_ros2.reader import read_ros2_messages

    stream = write(tmp_path / "bag", "mcap")
    files = sorted((tmp_path / "bag").glob("*.mcap"))
    assert len(files) == 1
    decoded = list(read_ros2_messages(str(files[0])))
    assert len(decoded) == len(stream)
    for (topic, expected), item in zip(stream, decoded):
        assert item.channel.topic == topic
        assert item.schema.name == expected.__msgtype__
        msg = item.ros_msg
        assert msg.header.stamp.sec == expected.header.stamp.sec
        assert msg.header.stamp.nanosec == expected.header.stamp.nanosec
        if topic.endswith("taxels"):
            assert list(msg.counts) == expected.counts.tolist()
            assert list(msg.voltages) == pytest.approx(expected.voltages.tolist())
        elif topic.endswith("wrench"):
            assert msg.wrench.force.z == pytest.approx(expected.wrench.force.z)
        else:
            assert list(msg.safe) == expected.safe.tolist()
            assert list(msg.lost_edges) == ["left"]
            assert msg.threshold == pytest.approx(1.05)


def test_writer_rejects_unknown_storage_and_type_change(tmp_path):
    with pytest.raises(ValueError, match="storage must be one of"):
        BagWriter(tmp_path / "x", storage="rosbag1")
    with BagWriter(tmp_path / "bag") as bag:
        bag.write("/a", taxels(1, 1))
        with pytest.raises(TypeError, match="carries prisma_msgs/msg/TaxelArray"):
            bag.write("/a", wrench(2, 0.0))


def test_message_without_header_needs_explicit_time(tmp_path):
    String = types("std_msgs/msg/String")
    with BagWriter(tmp_path / "bag") as bag:
        with pytest.raises(ValueError, match="has no header"):
            bag.write("/s", String(data="x"))
        bag.write("/s", String(data="x"), timestamp_ns=42)
    assert [(m.message.data, m.timestamp_ns) for m in read_bag(tmp_path / "bag")] == [("x", 42)]


@pytest.mark.parametrize("stop", [RuntimeError("converter bug"), KeyboardInterrupt()], ids=["error", "ctrl-c"])
def test_an_interrupted_bag_leaves_nothing_and_the_rerun_works(tmp_path, stop):
    stream = sample_stream()
    with pytest.raises(type(stop)):
        with BagWriter(tmp_path / "bag") as bag:
            bag.write_all(stream[:10])
            raise stop
    assert list(tmp_path.iterdir()) == []  # no bag, no staging directory
    write(tmp_path / "bag", "mcap")
    assert len(list(read_bag(tmp_path / "bag"))) == len(stream)
    assert sorted(p.name for p in (tmp_path / "bag").iterdir()) == ["bag.mcap", "metadata.yaml"]


def test_an_open_bag_is_not_at_its_path_until_closed(tmp_path):
    bag = BagWriter(tmp_path / "bag")
    bag.write_all(sample_stream()[:3])
    assert not (tmp_path / "bag").exists()
    bag.close()
    assert len(list(read_bag(tmp_path / "bag"))) == 3


def test_existing_bag_is_refused_unless_replacing(tmp_path):
    write(tmp_path / "bag", "mcap")
    with pytest.raises(FileExistsError, match="already exists"):
        BagWriter(tmp_path / "bag")
    with BagWriter(tmp_path / "bag", replace=True) as bag:
        bag.write("/prisma/thumb/taxels", taxels(5, 7))
    assert [m.message.counts[0] for m in read_bag(tmp_path / "bag")] == [7]


def test_missing_topics_are_named_with_what_the_bag_has(tmp_path):
    from prisma_common.bag import BagError, MissingTopicsError, bag_topics, require_topics

    write(tmp_path / "bag", "mcap")
    present = {"/prisma/thumb/taxels": "prisma_msgs/msg/TaxelArray",
               "/prisma/thumb/wrench": "geometry_msgs/msg/WrenchStamped",
               "/prisma/thumb/contact": "prisma_msgs/msg/ContactState"}
    assert bag_topics(tmp_path / "bag") == present
    assert require_topics(tmp_path / "bag", ["/prisma/thumb/taxels"]) == present
    with pytest.raises(MissingTopicsError) as err:
        require_topics(tmp_path / "bag", ["/prisma/thumb/taxels", "/prisma/index/taxels", "/ft_sensor/wrench"])
    assert err.value.missing == ["/prisma/index/taxels", "/ft_sensor/wrench"]
    assert str(err.value) == (
        f"bag {tmp_path / 'bag'} has no topics '/prisma/index/taxels', '/ft_sensor/wrench'; it has: "
        "/prisma/thumb/contact (prisma_msgs/msg/ContactState), /prisma/thumb/taxels (prisma_msgs/msg/TaxelArray), "
        "/prisma/thumb/wrench (geometry_msgs/msg/WrenchStamped)")
    (tmp_path / "empty").mkdir()
    with pytest.raises(BagError, match="is not a readable ROS 2 bag"):
        bag_topics(tmp_path / "empty")
    with pytest.raises(BagError, match="does not exist"):
        bag_topics(tmp_path / "nowhere")


def test_read_bag_with_only_absent_topics_reads_nothing(tmp_path):
    """rosbags reads an empty connection list as every topic; read_bag must not."""
    write(tmp_path / "bag", "mcap")
    assert list(read_bag(tmp_path / "bag", topics=["/prisma/index/taxels"])) == []
    assert len(list(read_bag(tmp_path / "bag", topics=[]))) == 0
    assert len(list(read_bag(tmp_path / "bag"))) == 44


def test_an_action_topics_bag_as_rosbag2_records_it_is_refused_in_one_line(tmp_path):
    """rosbag2 stores action feedback without a message definition (MCAP schema encoding 'unknown'),
    which rosbags cannot open: every reader of the bag says so in one line naming the topic and what to
    do, instead of rosbags' KeyError traceback."""
    from prisma_common.bag import BagError, bag_topics, require_topics
    from prisma_testing.recorded_bags import action_goals_bag

    bag = action_goals_bag(tmp_path / "hand_goals")
    expected = (f"bag {bag} holds topics recorded without a message definition (schema encoding 'unknown'), "
                "which the bag tools cannot read: /prisma/grasp/_action/feedback "
                "(prisma_msgs/action/Grasp_FeedbackMessage); record action topics into a bag of their own and give "
                'the tools the bag of sensor topics (docs/recording.md, "Record and replay")')
    for read in (lambda: bag_topics(bag), lambda: require_topics(bag, ["/prisma/thumb/taxels"]),
                 lambda: list(read_bag(bag, ["/prisma/thumb/taxels"]))):
        with pytest.raises(BagError) as refused:
            read()
        assert str(refused.value) == expected
    # the MCAP file alone, without the metadata.yaml that lists its topics
    [mcap] = bag.glob("*.mcap")
    with pytest.raises(BagError) as refused:
        bag_topics(mcap)
    assert str(refused.value).endswith("which the bag tools cannot read (rosbag2 records action feedback so); record "
                                       'action topics into a bag of their own and give the tools the bag of sensor '
                                       'topics (docs/recording.md, "Record and replay")')
