"""The scenario cache serves a network only to the code that built it: the key covers the pipeline's source."""

from __future__ import annotations

from pathlib import Path

from cosim.scenario import build
from cosim.scenario.behaviour import ScvBehaviour


def test_a_change_to_the_pipeline_code_builds_anew(tmp_path, monkeypatch):
    step = tmp_path / "step.py"
    step.write_text("CLEARANCE_M = 2.6\n")
    monkeypatch.setattr(build, "PIPELINE_SOURCES", (step,))
    before = build._network_key("osm-sha", ScvBehaviour())
    assert build._network_key("osm-sha", ScvBehaviour()) == before  # the same code: the cached network
    step.write_text("CLEARANCE_M = 2.0\n")
    assert build._network_key("osm-sha", ScvBehaviour()) != before


def test_every_module_of_the_scenario_pipeline_is_in_the_key():
    scenario = Path(build.__file__).parent
    sources = set(build.PIPELINE_SOURCES)
    assert set(scenario.glob("*.py")) - sources == {scenario / "check.py"}  # it runs a scenario, builds none
    assert Path(build.read_network.__code__.co_filename) in sources  # the net reader the fixes use
