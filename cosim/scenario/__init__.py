"""Scenario pipeline: OSM -> SUMO network, buildings, signs, demand and route table (paper IV-V)."""

from cosim.scenario.build import Scenario, ScenarioConfig, build_scenario, cache_dir

__all__ = ["Scenario", "ScenarioConfig", "build_scenario", "cache_dir"]
