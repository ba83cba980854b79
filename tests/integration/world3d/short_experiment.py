"""A short experiment config for the world3d tests that run `cosim experiment`."""

from __future__ import annotations


def short_experiment_config(path, name: str, osm, phase_s: float, participants: int, log: str = "") -> None:
    """An experiment config at ``path``: the three systems for ``phase_s`` each, ``participants`` daily
    commuters, on ``osm`` at low density with the ego leaving at once (``log``: the run's log section)."""
    phases = ", ".join(f"{{name: {n}, system: {s}, duration_s: {phase_s:g}}}"
                       for n, s in (("baseline", "none"), ("system_A", "A"), ("system_B", "B")))  # fmt: skip
    people = ", ".join(f"{{id: P{i + 1}, profile: daily_commuter}}" for i in range(participants))
    log_part = f", log: {{{log}}}" if log else ""
    path.write_text(f"name: {name}\nseed: 1\nphases: [{phases}]\nparticipants: [{people}]\n"
                    f"run: {{scenario: {{map: {osm}, demand: {{density: low}}}}, ego: {{depart_s: 0.0}}{log_part}}}\n")  # fmt: skip
