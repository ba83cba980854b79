"""Every random stream of a run, derived from the run seed by name, in this one place.

A stream is ``numpy.random.default_rng([seed, *tag])``: the tags are the ones the phases used before the
streams had names, so a given config and seed still produce the same numbers (and the same log bytes).
Add a stream by giving it a new, unused tag here; never change an existing tag.

The scenario build (``cosim.scenario``) draws its demand from ``default_rng(seed)`` itself: it runs
before, and apart from, a simulation.
"""

from __future__ import annotations

import numpy as np

# name -> the tag that follows the run seed in the generator's seed sequence
STREAMS: dict[str, tuple[int, ...]] = {
    "driver": (11,),  # the scripted driver (perception noise, wander); followed by ego.driver_seed
    "vanet": (23,),  # the VANET layer (CAM timing jitter, SOTDMA slot choices, shadowing field)
    "system_a": (31,),  # system A's stereo-camera measurement noise
    "route": (0x52,),  # extensions of the ego's route (cosim.phases.route)
    "traffic": (0x7A,),  # SCVs generated around the ego (cosim.phases.traffic)
}


def stream(seed: int, name: str, *extra: int) -> np.random.Generator:
    """The run's random stream ``name`` (``extra``: a sub-stream, e.g. the driver's own seed)."""
    try:
        tag = STREAMS[name]
    except KeyError:
        raise KeyError(f"unknown random stream {name!r} (streams: {', '.join(STREAMS)})") from None
    return np.random.default_rng([seed, *tag, *extra])
