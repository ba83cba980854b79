"""`cosim log export`: CSV and JSON lines that standard parsers read back (never Python repr)."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from cosim.cli import main
from cosim.errors import CosimError
from cosim.log import McapLog
from cosim.log.export import export_topic
from cosim.log.recorder import _scene


@pytest.fixture()
def log_file(tmp_path):
    path = tmp_path / "run.mcap"
    with McapLog(path, background=False) as log:
        for step in range(1, 4):
            t = step / 10
            log.write("/adas/events", t, {"t_s": t, "events": [
                {"t_s": t, "system": "A", "kind": "display", "old": "off", "new": "on", "value": 2.5},
                {"t_s": t, "system": "B", "kind": "data", "old": "no_cam", "new": "ok", "value": None}]})  # fmt: skip
            log.write("/vanet/rx", t, {"t_s": [t, t], "outcome": [0, 2], "rx_power_dbm": [-80.5, None]})
            log.write(
                "/ego/state", t, {"t_s": t, "leader_id": None if step == 2 else "scv1", "on_road": True}
            )
            log.write("/scene", t, _scene(t, ["scv1", "ego"], np.array([1.0, 2.0]), np.array([3.0, 4.0]),
                                          np.array([0.0, 90.0]), np.array([5.0, 4.5]), np.array([1.8, 1.8]),
                                          np.array([False, True])))  # fmt: skip
    return path


def test_csv_of_nested_events_has_dotted_columns_not_repr(log_file, tmp_path):
    out = tmp_path / "ev.csv"
    assert export_topic(log_file, "/adas/events", out, "csv") == 6
    text = out.read_text()
    assert "{'" not in text and "None" not in text
    rows = list(csv.DictReader(text.splitlines()))
    assert rows[0]["events.system"] == "A" and rows[1]["events.new"] == "ok"
    assert rows[0]["events.value"] == "2.5" and rows[1]["events.value"] == ""


def test_csv_of_columns_and_nulls(log_file, tmp_path):
    out = tmp_path / "rx.csv"
    export_topic(log_file, "/vanet/rx", out, "csv")
    rows = list(csv.DictReader(out.read_text().splitlines()))
    assert [r["outcome"] for r in rows[:2]] == ["0", "2"] and rows[1]["rx_power_dbm"] == ""
    export_topic(log_file, "/ego/state", out, "csv")
    rows = list(csv.DictReader(out.read_text().splitlines()))
    assert [r["leader_id"] for r in rows] == ["scv1", "", "scv1"] and rows[0]["on_road"] == "true"


@pytest.mark.parametrize("topic", ["/scene", "/adas/events", "/vanet/rx", "/ego/state"])
def test_json_lines_parse_back_to_the_logged_messages(log_file, tmp_path, topic):
    out = tmp_path / "x.jsonl"
    assert (
        main(["log", "export", str(log_file), "--topic", topic, "--format", "json", "--out", str(out)]) == 0
    )
    lines = [json.loads(line) for line in out.read_text().splitlines()]
    assert len(lines) == 3
    if topic == "/scene":
        assert [e["id"] for e in lines[0]["entities"]] == ["scv1", "ego"]
    if topic == "/adas/events":
        assert lines[0]["events"][1]["value"] is None


def test_scene_as_csv_keeps_json_cells(log_file, tmp_path):
    out = tmp_path / "scene.csv"
    assert main(["log", "export", str(log_file), "--topic", "/scene", "--out", str(out)]) == 0
    rows = list(csv.DictReader(out.read_text().splitlines()))
    assert json.loads(rows[0]["entities"])[0]["id"] == "scv1"


def test_unknown_topic_is_a_clear_error(log_file, tmp_path):
    with pytest.raises(CosimError, match="no topic /nope"):
        export_topic(log_file, "/nope", tmp_path / "x.csv")
    assert not (tmp_path / "x.csv").exists()
