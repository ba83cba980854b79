"""Refactor guard (issue 19): fixed runs must log the same message payloads, byte for byte, as recorded.

Two runs on the shipped Krems map: ``configs/default.yaml`` for 20 s (MuJoCo ego, lead car, radio, both
assistance systems evaluated), and participant P1 of ``configs/experiment.yaml`` with 10-s phases (traffic
generated around the ego, systems A and B switched by the protocol). For every topic the digest covers the
count, the log times and the payload bytes of its messages; the file's metadata (paths, config echo,
versions) is left out.

A change that is meant to alter the simulation's behaviour regenerates the digests, once, from a clean
checkout: ``COSIM_UPDATE_GOLDEN=1 pytest tests/integration/test_payload_identity.py``; a refactor must not.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections import defaultdict
from pathlib import Path

import pytest
from mcap.reader import make_reader

from cosim.experiment.protocol import load_experiment
from cosim.experiment.runner import run_experiment
from cosim.runconfig import load_run_config
from cosim.sim import Simulation

ROOT = Path(__file__).resolve().parents[2]
GOLDEN = ROOT / "tests" / "golden" / "run_payload_digests.json"

pytestmark = pytest.mark.slow  # 20 s + 3 x 10 s of simulated driving on Krems


def payload_digests(mcap_path: Path) -> dict[str, dict]:
    """topic -> {messages, sha256 over (log time, payload) of every message in file order}."""
    hashes: dict[str, hashlib._Hash] = defaultdict(hashlib.sha256)
    counts: dict[str, int] = defaultdict(int)
    with open(mcap_path, "rb") as fh:
        for _, channel, msg in make_reader(fh).iter_messages(log_time_order=False):
            h = hashes[channel.topic]
            h.update(msg.log_time.to_bytes(8, "little"))
            h.update(len(msg.data).to_bytes(8, "little"))
            h.update(msg.data)
            counts[channel.topic] += 1
    return {t: {"messages": counts[t], "sha256": hashes[t].hexdigest()} for t in sorted(hashes)}


@pytest.fixture(scope="module")
def digests(tmp_path_factory) -> dict[str, dict]:
    out = tmp_path_factory.mktemp("identity")
    cfg = load_run_config(ROOT / "configs" / "default.yaml", duration_s=20.0, seed=1)
    with Simulation(cfg, out_dir=out / "default", quiet=True) as sim:
        sim.run()
    exp, base = load_experiment(ROOT / "configs" / "experiment.yaml", participants=1, phase_duration_s=10)
    run_experiment(exp, base, out / "experiment", jobs=1, quiet=True)
    return {
        "default_20s_seed1": payload_digests(out / "default" / "run.mcap"),
        "experiment_P1_3x10s": payload_digests(out / "experiment" / "P1" / "run.mcap"),
    }


def test_run_payloads_are_identical_to_the_recorded_ones(digests):
    if os.environ.get("COSIM_UPDATE_GOLDEN") == "1":
        GOLDEN.write_text(json.dumps(digests, indent=1, sort_keys=True) + "\n")
        pytest.skip(f"payload digests written to {GOLDEN}")
    want = json.loads(GOLDEN.read_text())
    diff = [
        f"{run} {topic}: {want[run].get(topic)} -> {got.get(topic)}"
        for run, got in digests.items()
        for topic in sorted(set(got) | set(want.get(run, {})))
        if got.get(topic) != want.get(run, {}).get(topic)
    ]
    assert not diff, "run payloads changed (see the module docstring):\n" + "\n".join(diff)
