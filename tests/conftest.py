import os
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))  # tests/osm_factory.py, tests/testpaths.py


@pytest.fixture(scope="session", autouse=True)
def _cache_dir(tmp_path_factory):
    """Tests share one cache (built networks, route table), never the user's."""
    if "COSIM_TEST_CACHE" in os.environ:
        path = Path(os.environ["COSIM_TEST_CACHE"])
    else:
        path = tmp_path_factory.mktemp("cosim-cache")
    os.environ["COSIM_CACHE_DIR"] = str(path)
    yield path

