import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED_OSM = ROOT.parent / "shared" / "data" / "osm"
sys.path.insert(0, str(Path(__file__).parent))


@pytest.fixture(scope="session", autouse=True)
def _cache_dir(tmp_path_factory):
    """Tests share one cache (built networks, route table), never the user's."""
    if "COSIM_TEST_CACHE" in os.environ:
        path = Path(os.environ["COSIM_TEST_CACHE"])
    else:
        path = tmp_path_factory.mktemp("cosim-cache")
    os.environ["COSIM_CACHE_DIR"] = str(path)
    yield path


def shared_map(name: str) -> Path:
    path = SHARED_OSM / f"{name}.osm.gz"
    if not path.exists():
        path = ROOT / "configs" / "maps" / f"{name}.osm.gz"
    if not path.exists():
        pytest.skip(f"{name}.osm.gz is not available (../shared/data/osm missing)")
    return path
