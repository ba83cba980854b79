"""Column dicts (numpy arrays of equal length) -> JSON-ready lists; non-finite floats become null."""

from __future__ import annotations

import numpy as np


def json_columns(columns: dict[str, np.ndarray], decimals: dict[str, int] | None = None) -> dict[str, list]:
    out = {}
    for name, arr in columns.items():
        arr = np.asarray(arr)
        if arr.dtype.kind == "f":
            nd = (decimals or {}).get(name)
            # rounded in float64: a float32 rounded in float32 is still written with ~16 digits
            # (82.12 -> 82.12000274658203); float32 values are written as float64 either way
            vals = np.round(arr.astype(np.float64), nd) if nd is not None else arr
            finite = np.isfinite(vals)
            lst = vals.tolist()
            if not finite.all():
                lst = [v if ok else None for v, ok in zip(lst, finite.tolist(), strict=True)]
            out[name] = lst
        else:
            out[name] = arr.tolist()
    return out
