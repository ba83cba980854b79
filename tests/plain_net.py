"""Small SUMO networks for integration tests, built by netconvert from plain nodes and one-lane edges."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from cosim.sumo_bridge.tools import run_tool


def plain_net(folder: Path, nodes: dict[str, tuple[float, float]], edges: dict[str, tuple], *,
              priority_nodes: Iterable[str] | None = None, speed_mps: float = 13.89,
              options: Iterable[str] = ()) -> Path:  # fmt: skip
    """``folder``/n.net.xml from ``nodes`` (id -> x, y [m]) and ``edges`` (id -> (from node, to node, road
    priority[, lanes])), one lane unless given, at ``speed_mps``, no turnarounds. The nodes listed in
    ``priority_nodes`` are priority junctions and every other node a dead end; without it netconvert picks
    the types. ``options`` are further netconvert options (the scenario pipeline's, say)."""
    priority = None if priority_nodes is None else set(priority_nodes)  # a node id in it, not a substring

    def node_type(n: str) -> str:
        if priority is None:
            return ""
        return f' type="{"priority" if n in priority else "dead_end"}"'

    (folder / "n.nod.xml").write_text(
        "<nodes>"
        + "".join(f'<node id="{n}" x="{x}" y="{y}"{node_type(n)}/>' for n, (x, y) in nodes.items())
        + "</nodes>"
    )
    (folder / "n.edg.xml").write_text(
        "<edges>"
        + "".join(
            f'<edge id="{e}" from="{a}" to="{b}" numLanes="{lanes[0] if lanes else 1}" speed="{speed_mps}" '
            f'priority="{p}"/>'
            for e, (a, b, p, *lanes) in edges.items()
        )
        + "</edges>"
    )
    out = folder / "n.net.xml"
    run = run_tool("netconvert", ["-n", str(folder / "n.nod.xml"), "-e", str(folder / "n.edg.xml"),
                                  "--no-turnarounds", "true", *options, "-o", str(out)])  # fmt: skip
    assert run.returncode == 0, run.log
    return out
