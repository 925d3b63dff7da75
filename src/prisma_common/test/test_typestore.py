"""prisma_msgs interfaces: registration, CDR round trip with non-default values, parse errors."""
from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from rosbags.serde import SerdeError
from rosbags.typesys.store import Nodetype

from prisma_common import share_data
from prisma_common import typestore as ts_module
from prisma_common.typestore import (
    InterfaceParseError,
    get_typestore,
    parse_action_file,
    parse_msg_file,
    registered_prisma_types,
    types,
)

NUMPY_DTYPES = {
    "bool": np.bool_, "byte": np.uint8, "char": np.uint8, "int8": np.int8, "uint8": np.uint8,
    "int16": np.int16, "uint16": np.uint16, "int32": np.int32, "uint32": np.uint32,
    "int64": np.int64, "uint64": np.uint64, "float32": np.float32, "float64": np.float64,
}
EXPECTED_ACTION_PARTS = ("Goal", "Result", "Feedback", "FeedbackMessage")


def _base_value(name: str, counter: itertools.count):
    n = next(counter)
    if name == "string":
        return f"value-{n}"
    if name == "bool":
        return True
    if name.startswith("float"):
        return 0.5 + n
    return (n % 100) + 1


def _value(node, counter: itertools.count):
    """A non-default value for one field description of the typestore."""
    kind, detail = node
    if kind == Nodetype.BASE:
        return _base_value(detail[0], counter)
    if kind == Nodetype.NAME:
        return build_message(detail, counter)
    sub, length = detail
    count = length if kind == Nodetype.ARRAY else 3
    if sub[0] == Nodetype.BASE and sub[1][0] in NUMPY_DTYPES:
        return np.array([_base_value(sub[1][0], counter) for _ in range(count)],
                        dtype=NUMPY_DTYPES[sub[1][0]])
    return [_value(sub, counter) for _ in range(count)]


def build_message(typename: str, counter: itertools.count | None = None):
    counter = counter or itertools.count(1)
    store = get_typestore()
    _, fields = store.fielddefs[typename]
    return store.types[typename](**{name: _value(node, counter) for name, node in fields})


def assert_same(a, b, path="msg"):
    if isinstance(a, np.ndarray):
        np.testing.assert_array_equal(a, b, err_msg=path)
    elif isinstance(a, list):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{path}[{i}]")
    elif hasattr(a, "__dataclass_fields__"):
        for name in a.__dataclass_fields__:
            if name != "__msgtype__":
                assert_same(getattr(a, name), getattr(b, name), f"{path}.{name}")
    elif isinstance(a, float):
        assert a == pytest.approx(b), path
    else:
        assert a == b, path


def test_every_message_and_action_part_is_registered():
    names = set(registered_prisma_types())
    for msg in ("TaxelArray", "ContactState", "GloveFrame", "ObjectEstimate", "WeightEstimate"):
        assert f"prisma_msgs/msg/{msg}" in names
    for action in ("MoveMotors", "Grasp", "Manipulate"):
        for part in EXPECTED_ACTION_PARTS:
            assert f"prisma_msgs/action/{action}_{part}" in names


@pytest.mark.parametrize("typename", registered_prisma_types())
def test_cdr_round_trip_with_non_default_values(typename):
    store = get_typestore()
    message = build_message(typename)
    data = store.serialize_cdr(message, typename)
    back = store.deserialize_cdr(bytes(data), typename)
    assert_same(message, back)


def test_taxel_array_layout_is_fixed_nine():
    store = get_typestore()
    message = build_message("prisma_msgs/msg/TaxelArray")
    assert message.counts.shape == (9,) and message.voltages.shape == (9,)
    with pytest.raises(SerdeError):
        bad = types("prisma_msgs/msg/TaxelArray")(
            header=message.header, finger="thumb",
            counts=np.zeros(8, np.uint16), voltages=np.zeros(9, np.float32))
        store.serialize_cdr(bad, "prisma_msgs/msg/TaxelArray")


def test_feedback_message_wraps_goal_id_and_feedback():
    message = build_message("prisma_msgs/action/Manipulate_FeedbackMessage")
    assert message.goal_id.uuid.shape == (16,)
    assert message.feedback.__msgtype__ == "prisma_msgs/action/Manipulate_Feedback"


def test_unknown_type_lookup_names_the_type():
    with pytest.raises(KeyError, match="prisma_msgs/msg/Nope"):
        types("prisma_msgs/msg/Nope")


def test_msg_parse_error_names_file_and_line(tmp_path: Path):
    bad = tmp_path / "Bad.msg"
    bad.write_text("std_msgs/Header header\nfloat32 ok\nfloat32[9\n")
    with pytest.raises(InterfaceParseError, match=r"Bad\.msg:3"):
        parse_msg_file(bad)


def test_action_parse_error_counts_lines_across_sections(tmp_path: Path):
    bad = tmp_path / "Bad.action"
    bad.write_text("string motion\n---\nbool success\n---\nstring phase\n!!! nonsense\n")
    with pytest.raises(InterfaceParseError, match=r"Bad\.action:6"):
        parse_action_file(bad)


def test_action_without_three_sections_is_rejected(tmp_path: Path):
    bad = tmp_path / "Short.action"
    bad.write_text("string motion\n---\nbool success\n")
    with pytest.raises(InterfaceParseError, match="found 2 section"):
        parse_action_file(bad)


def test_interfaces_are_found_in_a_colcon_install_share(tmp_path: Path, monkeypatch):
    share = tmp_path / "install" / "prisma_msgs" / "share" / "prisma_msgs"
    (share / "msg").mkdir(parents=True)
    monkeypatch.setattr(share_data, "SOURCE_ROOT", None)  # as when installed: no source tree...
    monkeypatch.chdir(tmp_path)  # ...and run outside a workspace
    monkeypatch.delenv("PRISMA_MSGS_DIR", raising=False)
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(tmp_path / "install" / "prisma_msgs"))
    assert ts_module.find_interface_dir() == share
