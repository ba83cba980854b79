"""Extract the published PDR curves of Gonzalez-Martin et al. (IEEE TVT 68(2), 2019) into published_pdr.csv.

The authors publish the data of their PDR-vs-distance figures as MATLAB figures in their repository
https://github.com/msepulcre/C-V2X (``fig/CV2XMode4_beta<B>-lambda<L>-Pt<P>-S<S>-B190_PDR.fig``, commit 71d4c25):
each holds two lines, "PDR Simulation" (their Veins C-V2X mode 4 simulator) and "PDR Analytical" (the model),
sampled at 0, 25, ..., 500 m. A .fig file is a MAT v5 file; this reads it with scipy (not a cosim dependency:
``pip install scipy``) and writes one row per (configuration, distance). Usage:

    git clone https://github.com/msepulcre/C-V2X /tmp/C-V2X
    python validation/cv2x/extract_published.py /tmp/C-V2X/fig > validation/cv2x/published_pdr.csv
"""

import re
import sys
from pathlib import Path

import numpy as np
import scipy.io


def fig_lines(path: Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """DisplayName -> (x, y) of every line object in a MATLAB .fig file."""
    found: dict[str, tuple[np.ndarray, np.ndarray]] = {}

    def walk(node) -> None:
        if hasattr(node, "_fieldnames"):
            if getattr(node, "type", None) in ("graph2d.lineseries", "line"):
                p = node.properties
                name = getattr(p, "DisplayName", None)
                if isinstance(name, str) and name:
                    found[name] = (np.atleast_1d(p.XData).astype(float), np.atleast_1d(p.YData).astype(float))
            for f in node._fieldnames:
                walk(getattr(node, f))
        elif isinstance(node, np.ndarray) and node.dtype == object:
            for item in node.flat:
                walk(item)

    mat = scipy.io.loadmat(str(path), squeeze_me=True, struct_as_record=False)
    for key, value in mat.items():
        if not key.startswith("__"):
            walk(value)
    return found


def main(fig_dir: str) -> None:
    pat = re.compile(r"CV2XMode4_beta([\d.]+)-lambda(\d+)-Pt(\d+)-S(\d+)-B(\d+)_PDR\.fig")
    print("beta_veh_per_m,lambda_hz,pt_dbm,subchannels,size_bytes,distance_m,pdr_analytical,pdr_simulation")
    for path in sorted(Path(fig_dir).glob("*_PDR.fig")):
        m = pat.fullmatch(path.name)
        if not m:
            continue
        lines = fig_lines(path)
        xa, ya = lines["PDR Analytical"]
        xs, ys = lines["PDR Simulation"]
        assert np.array_equal(xa, xs), path
        for x, a, s in zip(xa, ya, ys, strict=True):
            print(f"{m[1]},{m[2]},{m[3]},{m[4]},{m[5]},{x:g},{a:.4f},{s:.4f}")


if __name__ == "__main__":
    main(sys.argv[1])
