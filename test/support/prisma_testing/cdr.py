"""A message through CDR and back with the rosbags typestore, as a bag writes and reads it: the
converters' round-trip tests (a converter that fills a field with the wrong type or shape fails here)."""
from __future__ import annotations

from typing import Any

from prisma_common.typestore import get_typestore


def cdr_round_trip(msg: Any) -> Any:
    """`msg` (a typestore message) serialized to CDR and deserialized again."""
    store = get_typestore()
    return store.deserialize_cdr(store.serialize_cdr(msg, msg.__msgtype__), msg.__msgtype__)
