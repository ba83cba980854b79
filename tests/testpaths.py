"""Where tests find the real OSM extracts (../shared/data/osm, else the maps shipped in configs/maps)."""

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED_OSM = ROOT.parent / "shared" / "data" / "osm"


def shared_map(name: str) -> Path:
    path = SHARED_OSM / f"{name}.osm.gz"
    if not path.exists():
        path = ROOT / "configs" / "maps" / f"{name}.osm.gz"
    if not path.exists():
        pytest.skip(f"{name}.osm.gz is not available (../shared/data/osm missing)")
    return path
