"""The paper's routing table (V.B): routes computed once are stored and reused by later builds and runs.

A SQLite file keyed by (network hash, origin edge, destination edge). SQLite makes it safe to share between
the parallel processes of an experiment or a sweep. A* itself is SUMO's (duarouter
``--routing-algorithm astar``).
"""

from __future__ import annotations

import sqlite3
from collections.abc import Iterable
from pathlib import Path
from xml.etree import ElementTree as ET

from cosim.errors import CosimError
from cosim.sumo_bridge.tools import run_tool


class RouteTable:
    def __init__(self, path: Path, net_hash: str):
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self.net_hash = net_hash
        self._db = sqlite3.connect(path, timeout=60)
        self._db.execute(
            "CREATE TABLE IF NOT EXISTS routes (net TEXT, origin TEXT, destination TEXT, edges TEXT, "
            "PRIMARY KEY (net, origin, destination))"
        )
        self.hits = 0
        self.computed = 0
        self.unreachable = 0

    def close(self) -> None:
        self._db.close()

    def forget(self, net_hashes: Iterable[str]) -> None:
        """Delete the routes of networks no longer cached (SQLite reuses their pages; the file stops growing)."""
        with self._db:
            self._db.executemany("DELETE FROM routes WHERE net=?", [(h,) for h in net_hashes])

    def lookup(self, pairs: Iterable[tuple[str, str]]) -> dict[tuple[str, str], tuple[str, ...] | None]:
        """Stored routes for the pairs that have one (None = stored as unreachable)."""
        found: dict[tuple[str, str], tuple[str, ...] | None] = {}
        cur = self._db.cursor()
        for origin, dest in pairs:
            row = cur.execute(
                "SELECT edges FROM routes WHERE net=? AND origin=? AND destination=?",
                (self.net_hash, origin, dest),
            ).fetchone()
            if row is not None:
                found[(origin, dest)] = tuple(row[0].split()) if row[0] else None
        return found

    def routes(
        self, pairs: list[tuple[str, str]], net_file: Path, workdir: Path
    ) -> dict[tuple[str, str], tuple[str, ...] | None]:
        """Routes for all pairs: from the table where stored, else computed with A* and stored."""
        unique = list(dict.fromkeys(pairs))
        result = self.lookup(unique)
        self.hits += len(result)
        missing = [p for p in unique if p not in result]
        if missing:
            computed = compute_routes(missing, net_file, workdir)
            with self._db:
                self._db.executemany(
                    "INSERT OR REPLACE INTO routes VALUES (?, ?, ?, ?)",
                    [(self.net_hash, o, d, " ".join(computed.get((o, d)) or ())) for o, d in missing],
                )
            for p in missing:
                result[p] = computed.get(p)
            self.computed += len(missing)
        self.unreachable += sum(1 for p in unique if not result.get(p))
        return result


def compute_routes(
    pairs: list[tuple[str, str]], net_file: Path, workdir: Path
) -> dict[tuple[str, str], tuple[str, ...]]:
    """Route origin/destination edge pairs with SUMO's A* (duarouter); unroutable pairs are left out."""
    trips = workdir / "od.trips.xml"
    out = workdir / "od.rou.xml"
    with trips.open("w") as fh:
        fh.write("<routes>\n")
        for i, (o, d) in enumerate(pairs):
            fh.write(f'    <trip id="{i}" depart="0" from="{o}" to="{d}"/>\n')
        fh.write("</routes>\n")
    run = run_tool(
        "duarouter",
        ["--net-file", str(net_file), "--route-files", str(trips), "--output-file", str(out),
         "--routing-algorithm", "astar", "--ignore-errors", "true", "--no-step-log", "true",
         "--write-trips", "false", "--alternatives-output", str(workdir / "od.alt.xml")],
    )  # fmt: skip
    if run.returncode != 0 or not out.exists():
        raise CosimError(f"duarouter failed: {(run.errors or ['no output'])[0]}")
    routes = {}
    for veh in ET.parse(out).getroot().iter("vehicle"):
        route = veh.find("route")
        if route is not None:
            routes[pairs[int(veh.get("id"))]] = tuple(route.get("edges").split())
    for f in (trips, out, workdir / "od.alt.xml"):
        f.unlink(missing_ok=True)
    return routes
