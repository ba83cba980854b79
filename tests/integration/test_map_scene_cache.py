"""The /map payload is drawn once per scenario and kept in its folder (cosim.log.map_scene.map_scene_json)."""

from __future__ import annotations

import os

from osm_factory import crossroads

import cosim.log.map_scene as map_scene
from cosim.log.writer import encode
from cosim.scenario import build_scenario


def test_map_scene_is_kept_and_redrawn_when_the_network_changes(tmp_path, monkeypatch):
    osm = tmp_path / "map.osm"
    crossroads().write(osm)
    scn = build_scenario(osm, tmp_path / "scn", density="low", seed=1, log=lambda *a: None)
    sdir = scn.sumocfg.parent
    drawn = encode(map_scene.map_scene_update(sdir))

    first = map_scene.map_scene_json(sdir)
    assert first == drawn  # the bytes the log wrote before the cache
    kept = list(sdir.glob("map_scene.*.json"))
    assert len(kept) == 1 and kept[0].read_bytes() == drawn
    assert not list(sdir.glob(".map_scene.*"))  # no temporary file left

    def no_drawing(_):
        raise AssertionError("drawn again although kept")

    monkeypatch.setattr(map_scene, "map_scene_update", no_drawing)
    assert map_scene.map_scene_json(sdir) == drawn

    # an edited network is drawn anew, and the stale payload goes
    net = sdir / "network.net.xml"
    st = net.stat()
    os.utime(net, ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000_000))
    monkeypatch.undo()
    assert map_scene.map_scene_json(sdir) == drawn
    now = list(sdir.glob("map_scene.*.json"))
    assert len(now) == 1 and now[0] != kept[0]


def test_map_scene_where_the_folder_cannot_be_written_is_drawn_each_time(tmp_path, monkeypatch):
    osm = tmp_path / "map.osm"
    crossroads().write(osm)
    scn = build_scenario(osm, tmp_path / "scn", density="low", seed=1, log=lambda *a: None)
    sdir = scn.sumocfg.parent

    def read_only(*a, **k):
        raise PermissionError("read-only file system")

    monkeypatch.setattr(map_scene.tempfile, "mkstemp", read_only)
    assert map_scene.map_scene_json(sdir) == encode(map_scene.map_scene_update(sdir))
    assert not list(sdir.glob("map_scene.*.json"))
