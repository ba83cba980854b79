"""Foxglove's official message schemas, in the JSON-schema form Foxglove uses for JSON-encoded channels.

cosim writes ``/map`` and ``/scene`` as JSON ``foxglove.SceneUpdate`` messages and ``/tf`` (the ego's frame)
as ``foxglove.FrameTransform``. Their channel schemas are not written by hand: it is generated from the official schema definitions in Foxglove's
``foxglove-schemas-protobuf`` package (a dev dependency) by :func:`from_protobuf`, with the rules of
Foxglove's own JSON-schema generator (time as ``{sec, nsec}``, enums as named constants, every field
required), and stored next to this module (``foxglove.<Type>.json``) so that a run needs neither that
package nor protobuf. ``tests/unit/test_log_schemas.py`` checks the stored file against the installed
package; after upgrading the package (or adding a type to ``NAMES``), regenerate with ``python cosim/log/foxglove_schemas.py``.
"""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path

HERE = Path(__file__).resolve().parent
NAMES = ("foxglove.SceneUpdate", "foxglove.FrameTransform")  # the Foxglove types cosim logs


def stored_path(name: str) -> Path:
    return HERE / f"{name}.json"


@cache
def stored(name: str) -> dict:
    """The stored JSON schema of a Foxglove message type (e.g. ``"foxglove.SceneUpdate"``)."""
    return json.loads(stored_path(name).read_text())


_TIME = {"type": "object", "title": "time",
         "properties": {"sec": {"type": "integer", "minimum": 0},
                        "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}},
         "required": ["sec", "nsec"]}  # fmt: skip
_DURATION = {"type": "object", "title": "duration",
             "properties": {"sec": {"type": "integer"},
                            "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}},
             "required": ["sec", "nsec"]}  # fmt: skip


def from_protobuf(name: str) -> dict:
    """The JSON schema of Foxglove message ``name`` from the official protobuf definitions (needs the
    ``foxglove-schemas-protobuf`` package)."""
    import importlib

    from google.protobuf.descriptor import FieldDescriptor as F

    short = name.removeprefix("foxglove.")
    module = importlib.import_module(f"foxglove_schemas_protobuf.{short}_pb2")
    descriptor = getattr(module, short).DESCRIPTOR
    scalars = {
        F.TYPE_DOUBLE: {"type": "number"}, F.TYPE_FLOAT: {"type": "number"},
        F.TYPE_INT32: {"type": "integer"}, F.TYPE_INT64: {"type": "integer"},
        F.TYPE_SINT32: {"type": "integer"}, F.TYPE_SINT64: {"type": "integer"},
        F.TYPE_SFIXED32: {"type": "integer"}, F.TYPE_SFIXED64: {"type": "integer"},
        F.TYPE_UINT32: {"type": "integer", "minimum": 0}, F.TYPE_UINT64: {"type": "integer", "minimum": 0},
        F.TYPE_FIXED32: {"type": "integer", "minimum": 0}, F.TYPE_FIXED64: {"type": "integer", "minimum": 0},
        F.TYPE_BOOL: {"type": "boolean"}, F.TYPE_STRING: {"type": "string"},
        F.TYPE_BYTES: {"type": "string", "contentEncoding": "base64"},
    }  # fmt: skip

    def message(d) -> dict:
        if d.full_name == "google.protobuf.Timestamp":
            return dict(_TIME)
        if d.full_name == "google.protobuf.Duration":
            return dict(_DURATION)
        props, required = {}, []
        for f in d.fields:
            if f.type == F.TYPE_MESSAGE:
                one = message(f.message_type)
            elif f.type == F.TYPE_ENUM:
                e = f.enum_type
                title = e.containing_type.full_name + e.name if e.containing_type else e.full_name
                one = {"title": title, "oneOf": [{"title": v.name, "const": v.number} for v in e.values]}
            else:
                one = dict(scalars[f.type])
            repeated = f.is_repeated if hasattr(f, "is_repeated") else f.label == F.LABEL_REPEATED
            props[f.name] = {"type": "array", "items": one} if repeated else one
            if not (f.has_presence and f.type != F.TYPE_MESSAGE):  # proto3 `optional` scalars may be left out
                required.append(f.name)
        return {"title": d.full_name, "type": "object", "properties": props, "required": required}

    return message(descriptor)


def regenerate() -> None:
    for name in NAMES:
        stored_path(name).write_text(json.dumps(from_protobuf(name), indent=1) + "\n")


if __name__ == "__main__":
    regenerate()
    print("wrote", ", ".join(str(stored_path(n)) for n in NAMES))
