"""Phases that plug into the lockstep loop (cosim.sim): the ego, the VANET layer, the assistance systems.

Each class takes the Simulation, registers its hooks with ``sim.add_hook(phase, fn)`` and publishes its
per-step results in ``sim.outputs``; the pure logic it drives lives in its own package.
"""
