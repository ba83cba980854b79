"""Every message of a short default run validates against the schema its channel declares, those schemas are
cosim's own (no catch-all), and the Foxglove-typed topics validate against Foxglove's official schemas
(generated from the ``foxglove-schemas-protobuf`` package, not from cosim's stored copy)."""

from __future__ import annotations

import json
import subprocess
import sys
from collections import Counter

import pytest

jsonschema = pytest.importorskip("jsonschema")
pytest.importorskip("foxglove_schemas_protobuf")

from mcap.reader import make_reader  # noqa: E402
from testpaths import ROOT as REPO  # noqa: E402  (tests/ is on sys.path: conftest.py)

from cosim.log import foxglove_schemas, schemas  # noqa: E402

DURATION_S = 15  # the ego from t <= 1 s, then its receptions, system B, channel-load frames, light changes
EXPECTED = {"/map", "/scene", "/tf", "/ego/state", "/traffic/vehicles", "/traffic/lights", "/vanet/tx", "/vanet/rx",
            "/vanet/load", "/vanet/step", "/adas/state"}  # fmt: skip


@pytest.fixture(scope="module")
def default_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("run")
    subprocess.run([sys.executable, "-m", "cosim.cli", "run", str(REPO / "configs/default.yaml"), "--duration",
                    str(DURATION_S), "--out", str(out / "r")], check=True, cwd=REPO, capture_output=True)  # fmt: skip
    return out / "r" / "run.mcap"


_DECODED: dict = {}


def _messages(path):
    """(schema, channel, decoded message) of every message, decoded once per file."""
    if path not in _DECODED:
        with open(path, "rb") as fh:
            _DECODED[path] = [(schema, channel, json.loads(message.data))
                              for schema, channel, message in make_reader(fh).iter_messages()]  # fmt: skip
    return _DECODED[path]


def test_every_message_validates_against_its_declared_schema(default_run):
    validators, counts, names = {}, Counter(), {}
    for schema, channel, msg in _messages(default_run):
        topic = channel.topic
        if topic not in validators:
            assert channel.message_encoding == "json" and schema.encoding == "jsonschema", topic
            declared = json.loads(schema.data)
            assert declared["title"] != schemas.GENERIC["title"], (
                f"{topic} is logged with the catch-all schema: declare it in cosim/log/schemas.py TOPIC_SCHEMAS"
            )
            assert declared == schemas.TOPIC_SCHEMAS[topic], (
                f"{topic}: the file's schema is not TOPIC_SCHEMAS'"
            )
            jsonschema.Draft202012Validator.check_schema(declared)
            validators[topic] = jsonschema.Draft202012Validator(declared)
            names[topic] = declared["title"]
        errors = list(validators[topic].iter_errors(msg))
        assert not errors, f"{topic} message {counts[topic]}: {errors[0].message} at {list(errors[0].path)}"
        counts[topic] += 1
    assert EXPECTED <= set(counts), f"topics missing from the run: {sorted(EXPECTED - set(counts))}"
    assert counts["/map"] == 1
    assert names["/scene"] == names["/map"] == "foxglove.SceneUpdate"
    assert names["/ego/state"] == "cosim.EgoState" and names["/vanet/rx"] == "cosim.VanetRx"


def test_foxglove_topics_validate_against_the_official_schemas(default_run):
    official = {name: jsonschema.Draft202012Validator(foxglove_schemas.from_protobuf(name))
                for name in foxglove_schemas.NAMES}  # fmt: skip
    seen = Counter()
    for schema, channel, msg in _messages(default_run):
        if channel.topic in schemas.FOXGLOVE_TOPICS:
            errors = list(official[schema.name].iter_errors(msg))
            assert not errors, f"{channel.topic}: {errors[0].message} at {list(errors[0].path)}"
            seen[channel.topic] += 1
    assert seen["/map"] == 1 and seen["/scene"] >= DURATION_S - 1 and seen["/tf"] > 0
    # the static map has every part the issue asks for
    first = next(m for _, c, m in _messages(default_run) if c.topic == "/map")
    ids = {e["id"] for e in first["entities"]}
    assert {"roads", "lane_markings", "buildings", "signs", "traffic_lights"} <= ids


def _layout_topics(node, out: set[str]) -> None:
    """Topics a Foxglove layout names: 3D topic keys and the topic part of every message path."""
    if isinstance(node, dict):
        for k, v in node.items():
            if k == "topics" and isinstance(v, dict):
                out.update(v)
            elif k == "value" and isinstance(v, str) and v.startswith("/"):
                out.add(v.split(".")[0])
            else:
                _layout_topics(v, out)
    elif isinstance(node, list):
        for v in node:
            _layout_topics(v, out)


def _layout_panels(node, out: list[str]) -> None:
    if isinstance(node, str):
        out.append(node)
    elif isinstance(node, dict):
        for k in ("first", "second"):
            _layout_panels(node.get(k), out)


def test_shipped_foxglove_layout_names_only_topics_a_default_run_writes(default_run):
    layout = json.loads((REPO / "docs/foxglove/cosim.json").read_text())
    written = {c.topic for _, c, _ in _messages(default_run)}
    named: set[str] = set()
    _layout_topics(layout["configById"], named)
    assert {"/map", "/scene", "/adas/state", "/vanet/load", "/vanet/rx"} <= named
    assert named <= written, (
        f"the layout names topics a default run does not write: {sorted(named - written)}"
    )
    panels: list[str] = []
    _layout_panels(layout["layout"], panels)
    assert sorted(panels) == sorted(layout["configById"]), "every configured panel is placed, and only those"
    known = {
        "3D",
        "Plot",
        "StateTransitions",
        "RawMessages",
        "Table",
        "Indicator",
    }  # Foxglove's built-in panels
    assert {p.split("!")[0] for p in panels} <= known
    # every plotted field exists in the topic's schema
    for panel in layout["configById"].values():
        for path in panel.get("paths", []):
            topic, _, field = path["value"].partition(".")
            name = field.split("[")[0]
            assert name in schemas.TOPIC_SCHEMAS[topic]["properties"], path["value"]
