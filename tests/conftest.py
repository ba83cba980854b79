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


def pytest_configure(config):
    config.addinivalue_line(
        "markers", "own_process: run the test in a fresh Python process (libsumo: one simulation per process)"
    )


@pytest.hookimpl(tryfirst=True)
def pytest_pyfunc_call(pyfuncitem):
    """Tests marked own_process run again, alone, in a child pytest; the parent reports its outcome.

    libsumo keeps global state per process, and a second simulation in the same process can crash
    natively; a child process per test keeps one test's simulator from taking the whole session down.
    """
    if pyfuncitem.get_closest_marker("own_process") is None or os.environ.get("COSIM_TEST_CHILD"):
        return None
    import subprocess

    env = {**os.environ, "COSIM_TEST_CHILD": "1"}
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "--no-header", pyfuncitem.nodeid],
        cwd=pyfuncitem.config.rootpath, env=env, capture_output=True, text=True,
    )  # fmt: skip
    if proc.returncode == 5:
        pytest.skip("skipped in its own process")
    if proc.returncode != 0:
        pytest.fail(f"failed in its own process (exit {proc.returncode}):\n{proc.stdout[-6000:]}{proc.stderr[-2000:]}",
                    pytrace=False)  # fmt: skip
    return True
