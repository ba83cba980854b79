"""The scenario cache serves a network only to the code that built it: the key covers the pipeline's source."""

from __future__ import annotations

import json
import os
from pathlib import Path

from cosim.scenario import build
from cosim.scenario.behaviour import ScvBehaviour


def test_a_change_to_the_pipeline_code_builds_anew(tmp_path, monkeypatch):
    step = tmp_path / "step.py"
    step.write_text("CLEARANCE_M = 2.6\n")
    monkeypatch.setattr(build, "PIPELINE_SOURCES", (step,))
    before = build._network_key("osm-sha", ScvBehaviour(), "auto")
    # the same code: the cached network
    assert build._network_key("osm-sha", ScvBehaviour(), "auto") == before
    step.write_text("CLEARANCE_M = 2.0\n")
    assert build._network_key("osm-sha", ScvBehaviour(), "auto") != before


def test_the_driving_side_setting_is_in_the_key():
    keys = {side: build._network_key("osm-sha", ScvBehaviour(), side) for side in ("auto", "right", "left")}
    assert len(set(keys.values())) == 3


def test_every_module_of_the_scenario_pipeline_is_in_the_key():
    scenario = Path(build.__file__).parent
    sources = set(build.PIPELINE_SOURCES)
    assert set(scenario.glob("*.py")) - sources == {scenario / "check.py"}  # it runs a scenario, builds none
    assert Path(build.read_network.__code__.co_filename) in sources  # the net reader the fixes use


def _entry(root: Path, kind: str, key: str, used: float, network: str = "") -> None:
    d = root / kind / key
    d.mkdir(parents=True)
    f = d / ("report.json" if kind == "scenarios" else "network.json")
    f.write_text(json.dumps({"cache": {"network_key": network}}))
    os.utime(f, (used, used))


def test_the_cache_forgets_the_scenarios_unused_longest_and_networks_nothing_refers_to(tmp_path, monkeypatch):
    """A sweep builds a scenario per seed (5-7 MB each): beyond COSIM_CACHE_MAX_SCENARIOS the ones unused
    longest go, never one used within a day (an experiment's participants still read theirs) nor the one
    just built; then the networks no scenario kept refers to, with their routes."""
    from cosim.scenario.routetable import RouteTable

    now, day = 1.0e9, build.CACHE_KEEP_S
    monkeypatch.setenv("COSIM_CACHE_MAX_SCENARIOS", "2")
    for key, age, net in (("old1", 3 * day, "netA"), ("old2", 2 * day, "netB"), ("new1", 0.5 * day, "netB"),
                          ("just", 3 * day, "netC"), ("new2", 10.0, "netB")):  # fmt: skip
        _entry(tmp_path, "scenarios", key, now - age, net)
    for key, age in (("netA", 3 * day), ("netB", 3 * day), ("netC", 3 * day), ("netD", 0.2 * day)):
        _entry(tmp_path, "networks", key, now - age)
    table = RouteTable(tmp_path / "routes.sqlite", "netA")
    with table._db:
        table._db.executemany("INSERT INTO routes VALUES (?, ?, ?, ?)",
                              [("netA", "a", "b", "a x b"), ("netB", "a", "b", "a y b")])  # fmt: skip
    table.close()

    removed = build.evict_stale(tmp_path, keep=frozenset({"just"}), now=now)
    # 5 scenarios, 2 allowed: the two unused longest go; "just" is kept, the others are younger than a day
    assert sorted(removed) == ["netA", "old1", "old2"]
    assert sorted(p.name for p in (tmp_path / "scenarios").iterdir()) == ["just", "new1", "new2"]
    # netB and netC are still referred to; netD by nothing, but used within the day
    assert sorted(p.name for p in (tmp_path / "networks").iterdir()) == ["netB", "netC", "netD"]
    table = RouteTable(tmp_path / "routes.sqlite", "netA")
    assert table.lookup([("a", "b")]) == {}  # netA's routes are gone ...
    table.close()
    table = RouteTable(tmp_path / "routes.sqlite", "netB")
    assert table.lookup([("a", "b")]) == {("a", "b"): ("a", "y", "b")}  # ... netB's stay
    table.close()
    assert not list(tmp_path.glob(".evicted-*"))
    assert build.evict_stale(tmp_path, keep=frozenset({"just"}), now=now) == []  # nothing more to do
