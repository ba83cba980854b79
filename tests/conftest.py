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
    elif os.environ.get("COSIM_TEST_CHILD") and os.environ.get("COSIM_CACHE_DIR"):
        path = Path(os.environ["COSIM_CACHE_DIR"])  # an own_process test: its parent's cache, maps built once
    elif "PYTEST_XDIST_WORKER" in os.environ:  # one cache for all workers of the run: a map is built once
        path = tmp_path_factory.getbasetemp().parent / "cosim-cache"  # (concurrent builds publish atomically)
        path.mkdir(exist_ok=True)
    else:
        path = tmp_path_factory.mktemp("cosim-cache")
    os.environ["COSIM_CACHE_DIR"] = str(path)
    yield path


def pytest_configure(config):
    config.addinivalue_line(
        "markers", "own_process: run the test in a fresh Python process (libsumo: one simulation per process)"
    )


def _child_outcome(junit_xml: Path) -> tuple[str, str]:
    """(outcome, message) of the one test a child pytest ran: passed, failed, skipped or xfailed."""
    import xml.etree.ElementTree as ET

    try:
        cases = list(ET.parse(junit_xml).getroot().iter("testcase"))
    except (OSError, ET.ParseError):
        return "failed", "the child pytest wrote no report"
    if len(cases) != 1:
        return "failed", f"the child pytest ran {len(cases)} tests instead of one"
    for tag in ("failure", "error", "skipped"):
        el = cases[0].find(tag)
        if el is not None:
            message = el.get("message", "")
            if tag == "skipped":
                return ("xfailed" if el.get("type") == "pytest.xfail" else "skipped"), message
            return "failed", message
    return "passed", ""


@pytest.hookimpl(tryfirst=True)
def pytest_pyfunc_call(pyfuncitem):
    """Tests marked own_process run again, alone, in a child pytest; the parent reports its outcome (passed,
    failed, skipped with the child's reason, or xfailed), read from the child's JUnit XML report.

    libsumo keeps global state per process, and a second simulation in the same process can crash
    natively; a child process per test keeps one test's simulator from taking the whole session down.
    """
    if pyfuncitem.get_closest_marker("own_process") is None or os.environ.get("COSIM_TEST_CHILD"):
        return None
    import subprocess
    import tempfile

    env = {**os.environ, "COSIM_TEST_CHILD": "1"}
    with tempfile.TemporaryDirectory() as tmp:
        report = Path(tmp) / "child.xml"
        proc = subprocess.run(
            [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "--no-header", "--junitxml",
             str(report), pyfuncitem.nodeid],
            cwd=pyfuncitem.config.rootpath, env=env, capture_output=True, text=True,
        )  # fmt: skip
        outcome, message = _child_outcome(report)
    if outcome == "skipped":
        pytest.skip(f"in its own process: {message}")
    if outcome == "xfailed":
        pytest.xfail(f"in its own process: {message}")
    if outcome != "passed" or proc.returncode != 0:
        pytest.fail(f"failed in its own process (exit {proc.returncode}): {message}\n"
                    f"{proc.stdout[-6000:]}{proc.stderr[-2000:]}", pytrace=False)  # fmt: skip
    return True
