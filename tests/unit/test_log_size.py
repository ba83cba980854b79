"""Issue 20 item 3: what makes the default log smaller keeps its content readable and exact."""

from __future__ import annotations

import json

import numpy as np
import zstandard

from cosim.log import read
from cosim.log.columns import json_columns
from cosim.log.writer import ZSTD_LEVEL, McapLog
from cosim.phases.vanet import _logged_tx
from cosim.runconfig import load_run_config


def test_float32_columns_are_rounded_to_their_decimals():
    cols = {
        "distance_m": np.array([82.12, 3.456789], dtype=np.float32),
        "n": np.array([1, 2], dtype=np.int32),
    }
    out = json_columns(cols, {"distance_m": 2})
    assert json.dumps(out) == '{"distance_m": [82.12, 3.46], "n": [1, 2]}'
    # within a float32's precision of the value it stands for
    assert np.float32(out["distance_m"][0]) == np.float32(82.12)


def _tx(rows):
    keys = ("sender_slot", "frame", "slot", "gen_t_s", "size_bytes")
    return {k: np.array([r[i] for r in rows], dtype=np.float64 if k == "gen_t_s" else np.int64)
            for i, k in enumerate(keys)}  # fmt: skip


def test_tx_log_rx_keeps_the_transmissions_with_a_reception_row():
    tx = _tx([(1, 30, 5, 29.9, 300), (2, 30, 7, 29.95, 300), (1, 30, 9, 30.0, 310), (3, 30, 11, 30.05, 300)])
    rx = _tx([(2, 30, 7, 29.95, 0), (2, 30, 7, 29.95, 0), (1, 30, 9, 30.0, 0)])
    kept = _logged_tx(tx, rx, "rx")
    assert kept["sender_slot"].tolist() == [2, 1] and kept["slot"].tolist() == [7, 9]
    assert kept["size_bytes"].tolist() == [300, 310]  # whole rows, in their order
    assert all(len(v) == 0 for v in _logged_tx(tx, rx, "none").values())
    assert all(len(v) == 0 for v in _logged_tx(tx, _tx([]), "rx").values())


def test_chunks_are_zstd_at_the_chosen_level_and_read_back(tmp_path):
    path = tmp_path / "x.mcap"
    with McapLog(path, background=False) as log:
        for i in range(50):
            log.write("/events", i * 0.1, {"t_s": i * 0.1, "step": i, "kind": "k", "vehicle": "v", "detail": "",
                                           "value": None})  # fmt: skip
    got = read(path)
    assert got.counts == {"/events": 50} and got["/events"]["step"].tolist() == list(range(50))
    assert ZSTD_LEVEL > 3  # better than the mcap library's default


def test_default_rates():
    cfg = load_run_config(None)
    assert cfg.log.traffic_every_steps == 20 and cfg.log.flush_every_s == 5.0
    assert cfg.vanet.tx_log == "rx" and cfg.vanet.rx_log == "ego"
    shipped = load_run_config("configs/default.yaml")
    assert shipped.log.traffic_every_steps == 20


def test_zstandard_is_deterministic_at_the_level():
    data = b'{"x":[1.25,2.5]}' * 1000
    c = zstandard.ZstdCompressor(level=ZSTD_LEVEL)
    assert c.compress(data) == zstandard.ZstdCompressor(level=ZSTD_LEVEL).compress(data)
