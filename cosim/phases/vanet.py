"""The VANET phase: every vehicle a station, one lockstep step of CAMs over SOTDMA through the aether."""

from __future__ import annotations

from cosim.log.columns import json_columns
from cosim.scenario.buildings import load_buildings
from cosim.seeds import stream
from cosim.vanet import VanetLayer, VanetParams

_DECIMALS = {
    "distance_m": 2,
    "rx_power_dbm": 2,
    "t_s": 4,
    "gen_t_s": 4,
    "busy_ratio": 4,
    "airtime_ratio": 4,
    "cbr_mean": 4,
    "cbr_p95": 4,
    "cbr_ego": 4,
}


class VanetPhase:
    def __init__(self, sim, params: VanetParams):
        buildings, _ = load_buildings(sim.scenario.buildings_file)
        self.layer = VanetLayer(params, buildings, stream(sim.config.seed, "vanet"))
        self.sim = sim
        sim.add_hook("vanet", self.step)

    def step(self, sim) -> None:
        res = self.layer.step(sim.world, sim.world.step, sim.step_s)
        sim.outputs["vanet"] = res
        if sim.mcap is not None:
            log = sim.outputs.setdefault("log", {})
            for topic, cols in res.columns().items():
                n = len(next(iter(cols.values()))) if cols else 0
                if n:
                    log[topic] = json_columns(cols, _DECIMALS)

    def ego_obu(self):
        return self.layer.obu_view(self.sim.world)
