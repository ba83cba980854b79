"""The phases the lockstep loop runs (``cosim.sim.Simulation._build_schedule``): the radio, the assistance
systems, the traffic around the ego, the ego's route, the ego itself and the lead vehicle.

A phase is an object with ``step(...)`` and ``close()``. ``vanet``, ``adas``, ``traffic`` and ``route`` (and
``cosim.health.DriveHealth``) are given narrow ports when the Simulation builds them: their config, their
random stream (``cosim.seeds``), the snapshot (``cosim.world.World``) and the SUMO operations they need as
named bridge methods (a ``Protocol`` in each module; ``cosim.sumo_bridge.SumoBridge`` provides them). They
return their results (the Simulation keeps them in ``StepOutputs``) and never touch SUMO or the
Simulation. ``ego`` and ``lead`` still take the Simulation (issue 15 is changing them). The pure logic each
drives lives in its own package.
"""
